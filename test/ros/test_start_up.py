"""Which runs start streaming before their spring sample, modes or plan are ready (start_up)."""
from __future__ import annotations

import dataclasses

from helpers import hanging_sheet
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.ros.start.start_up import (FIRST_MODES, first_values, STAGED_DOF,
                                                 STAGED_SPRINGS)
from modal_spring_ros.scenes.resources import load_scene
from modal_spring_ros.scenes.schema import scene_from_dict
import pytest

SAMPLED = SimulationConfig(forces='sampled')
#: the lowest 32 modes, as the stream benchmark asks
LOWEST_32 = FilterBand('lowpass', high=31.0, by='index')


@pytest.fixture(scope='module')
def large():
    scene = load_scene('sheet_100x100')
    assert scene.n_springs >= STAGED_SPRINGS and scene.n_free_dof < STAGED_DOF
    return scene


@pytest.fixture(scope='module')
def huge():
    scene = scene_from_dict(hanging_sheet(160))
    assert scene.n_free_dof >= STAGED_DOF
    return scene


def test_a_large_scene_asked_for_sampled_springs_starts_with_refreshed_ones(large):
    assert first_values(SAMPLED, large) == {'modal.forces': 'refreshed'}


@pytest.mark.parametrize('config', [
    SimulationConfig(forces='exact'), SimulationConfig(forces='refreshed'),
    dataclasses.replace(SAMPLED, method='full')])
def test_other_runs_start_as_asked(large, config):
    assert first_values(config, large) == {}


def test_a_scene_below_the_size_starts_as_asked():
    scene = load_scene('sheet_32x32')
    assert scene.n_springs < STAGED_SPRINGS
    assert first_values(SAMPLED, scene) == {}


@pytest.mark.parametrize('band', [
    LOWEST_32, FilterBand(), FilterBand('lowpass', high=40.0),
    FilterBand('lowpass', high=40.0, order=4), FilterBand('highpass', low=3.0, by='index'),
    FilterBand('bandstop', low=2.0, high=5.0, by='index'),
    FilterBand('bandpass', low=7.0, high=20.0, by='index')])
def test_a_huge_scene_streams_its_lowest_modes_first_where_the_band_keeps_more(huge, band):
    config = SimulationConfig(forces='sampled', band=band)
    assert first_values(config, huge) == {'modal.forces': 'refreshed',
                                          'modal.max_modes': FIRST_MODES}
    assert first_values(dataclasses.replace(config, forces='exact'), huge) == {
        'modal.max_modes': FIRST_MODES}


@pytest.mark.parametrize('band', [
    FilterBand('lowpass', high=FIRST_MODES - 1.0, by='index'),    # no more than the first
    FilterBand('bandpass', low=FIRST_MODES, high=31.0, by='index'),   # none of the first
    FilterBand('highpass', low=10.0), FilterBand('bandpass', low=5.0, high=30.0),
    FilterBand('bandstop', low=0.1, high=30.0),     # by frequency: the lowest may be out
    FilterBand('lowpass', high=40.0, gains=('0:10:-80',))])
def test_a_huge_scene_starts_as_asked_where_its_first_modes_may_not_serve(huge, band):
    config = SimulationConfig(forces='exact', band=band)
    assert first_values(config, huge) == {}


def test_a_huge_scene_starts_as_asked_when_it_may_compute_no_more_modes(huge):
    config = SimulationConfig(band=LOWEST_32, max_modes=FIRST_MODES)
    assert first_values(config, huge) == {}


@pytest.mark.parametrize('scene', ['sheet_10x10', 'sheet_100x100'])
def test_an_automatic_plan_of_every_mode_streams_the_full_run_first(scene):
    for config in (SimulationConfig(auto=True), dataclasses.replace(SAMPLED, auto=True)):
        assert first_values(config, load_scene(scene)) == {'method': 'full', 'modal.auto': False}


def test_an_automatic_plan_of_a_band_streams_the_band_on_its_rest_modes_first(large, huge):
    band = FilterBand('lowpass', high=20.0)
    assert first_values(SimulationConfig(band=band, auto=True), load_scene('sheet_10x10')) == {
        'modal.auto': False, 'modal.basis': 'rest'}
    # staged as the band itself is on large scenes: sampled springs asked, refreshed first
    assert first_values(SimulationConfig(band=band, auto=True, forces='sampled'), large) == {
        'modal.auto': False, 'modal.basis': 'rest', 'modal.forces': 'refreshed'}
    assert first_values(SimulationConfig(band=LOWEST_32, auto=True), huge) == {
        'modal.auto': False, 'modal.basis': 'rest', 'modal.max_modes': FIRST_MODES}
    # a huge scene's full run would take the core its plan needs: its lowest modes stream
    assert first_values(SimulationConfig(auto=True), huge) == {
        'modal.auto': False, 'modal.basis': 'rest', 'modal.max_modes': FIRST_MODES}

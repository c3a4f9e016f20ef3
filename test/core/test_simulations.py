"""
The simulation contract.

Registries, what every method offers, the configuration's rules, and state changes that leave no
half-built state (a reset during a band fade).
"""
from __future__ import annotations

import dataclasses
import math
import threading

from modal_spring_ros.core.config import ConfigError, SimulationConfig
from modal_spring_ros.core.factory import AUTO_DT_SAFETY, build_simulation, rebuild
from modal_spring_ros.core.filter_band import BandError, FilterBand
from modal_spring_ros.core.integrators import integrator, INTEGRATORS
from modal_spring_ros.core.simulations import (FullSimulation, METHODS, MIN_DT_S, ModalSimulation,
                                               SimulationStatus, UnstableStepError)
from modal_spring_ros.core.simulations.stepped_set import SteppedSet
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest


@pytest.fixture(scope='module')
def sheet():
    return load_scene('sheet_10x10')


def test_registries_map_names_to_classes():
    assert METHODS == {'modal': ModalSimulation, 'full': FullSimulation}
    assert sorted(INTEGRATORS) == ['average', 'explicit']
    for name, cls in INTEGRATORS.items():
        assert cls.name == name and isinstance(integrator(name), cls)
    with pytest.raises(ValueError, match="integrator 'rk4' must be one of explicit, average"):
        integrator('rk4')


@pytest.mark.parametrize('method', sorted(METHODS))
def test_every_method_offers_the_contract(sheet, method):
    band = FilterBand('lowpass', 0.0, 20.0)
    sim = build_simulation(sheet, SimulationConfig(method=method, band=band, basis='rest'))
    status = sim.status()
    assert isinstance(status, SimulationStatus)
    assert status.method == method and status.integrator == 'explicit'
    assert status.time == 0.0 and status.steps == 0 and status.max_strain == 0.0
    assert sim.band == band and sim.force_refresh == 1 and sim.force_report().error is None
    assert sim.mode_choice is None and not sim.fading and not sim.truncated
    f = sim.basis.frequencies_hz[sim.kept_modes]
    if method == 'modal':
        assert f.max() <= 20.0 and status.coordinates == sim.kept_modes.size == 4
        assert status.band == 'lowpass <= 20 Hz' and status.basis == 'rest: 4 modes'
    else:  # every mode takes part; the band waits for a switch to modal
        assert sim.kept_modes.size == 180 and status.coordinates == 180
        assert status.band == 'full' and status.basis == 'physical: every free DOF'
    sim.step(10)
    again = sim.with_dt(sim.dt / 2)
    assert type(again) is type(sim) and again.dt == sim.dt / 2 and again.time == 0.0
    assert again.band == band and again.integrator == sim.integrator


def test_with_dt_keeps_the_automatic_choice(sheet):
    sim = build_simulation(sheet, SimulationConfig(auto=True, tolerance=0.05))
    again = sim.with_dt(sim.dt / 2)
    assert again.mode_choice is sim.mode_choice and again.force_refresh == sim.force_refresh
    assert again.kept_modes.tolist() == sim.kept_modes.tolist()


@pytest.mark.parametrize('basis', ['rest', 'derivatives'])
def test_a_run_without_a_step_is_built_once_at_its_share_of_the_stability_limit(
        sheet, basis, monkeypatch):
    """The step comes from what the band steps, found before the forces are set up."""
    sheet = dataclasses.replace(sheet, default_dt=None)
    builds = []
    original = SteppedSet.build
    monkeypatch.setattr(SteppedSet, 'build', staticmethod(
        lambda *args, **kwargs: builds.append(1) or original(*args, **kwargs)))
    sim = build_simulation(sheet, SimulationConfig(band=FilterBand('lowpass', 0, 20, 'hz'),
                                                   basis=basis))
    assert len(builds) == 1
    assert sim.dt == pytest.approx(AUTO_DT_SAFETY * sim.stability_limit(), rel=1e-12)
    assert sim.settings.dt == sim.dt and sim.settings.step_share is None
    given = build_simulation(sheet, SimulationConfig(band=FilterBand('lowpass', 0, 20, 'hz'),
                                                     basis=basis, dt=sim.dt / 2))
    assert given.dt == sim.dt / 2 and len(builds) == 2


def test_a_reset_during_a_band_fade_settles_the_band_and_rests(sheet):
    """
    One reset while a band change is still fading keeps the run whole.

    One reset while a band change is still fading used to raise (shapes (0,) and (180,)) and leave
    the run half-changed, killing the node's stream.
    """
    sim = build_simulation(sheet, SimulationConfig(basis='rest'))
    sim.step(20)
    sim.set_band(FilterBand('lowpass', 0, 20, 'hz'), 0.5)
    sim.step()
    assert sim.fading and sim.stepped_modes.size == 180
    sim.reset()
    assert not sim.fading and sim.time == 0.0 and sim.steps == 0
    assert sim.stepped_modes.tolist() == sim.kept_modes.tolist() == [0, 1, 2, 3]
    np.testing.assert_array_equal(sim.displacement(), 0.0)
    sim.step(200)  # and it runs on, like a fresh run of that band
    fresh = build_simulation(sheet, SimulationConfig(band=FilterBand('lowpass', 0, 20, 'hz'),
                                                     basis='rest'))
    fresh.step(200)
    np.testing.assert_allclose(sim.positions(), fresh.positions(), rtol=0, atol=1e-12)


def test_a_failed_band_change_leaves_the_run_as_it_was(sheet):
    sim = build_simulation(sheet, SimulationConfig(band=FilterBand('lowpass', 0, 20, 'hz')))
    sim.step(30)
    before = (sim.positions(), sim.kept_modes.copy(), sim.band)
    with pytest.raises(BandError, match='keeps no mode'):
        sim.set_band(FilterBand('lowpass', 0, 1, 'hz'))
    np.testing.assert_array_equal(sim.positions(), before[0])
    assert sim.kept_modes.tolist() == before[1].tolist() and sim.band == before[2]


def test_preparing_switches_from_another_thread_while_stepping_and_fading(sheet):
    """
    The active set is read as one snapshot.

    A thread preparing switches while the run steps, switches and resets never sees a half-changed
    set.
    """
    sim = build_simulation(sheet, SimulationConfig(transition_s=0.01))
    bands = [FilterBand('lowpass', 0, 20, 'hz'), FilterBand('bandpass', 5, 40, 'hz'),
             FilterBand('highpass', 10, 0, 'hz'), FilterBand()]
    errors, stop = [], threading.Event()

    def prepare():
        k = 0
        while not stop.is_set():
            try:
                sim.prepare_switch(bands[k % len(bands)])
            except Exception as exc:  # collected: the test fails on any
                errors.append(exc)
            k += 1

    thread = threading.Thread(target=prepare)
    thread.start()
    try:
        for k in range(120):
            sim.set_band(bands[k % len(bands)])
            sim.step(5)
            if k % 7 == 0:
                sim.reset()
    finally:
        stop.set()
        thread.join()
    assert errors == []
    assert np.isfinite(sim.positions()).all()


@pytest.mark.parametrize('changes, message', [
    ({'method': 'fem'}, "method 'fem' must be one of modal, full"),
    ({'integrator': 'rk4'}, "integrator 'rk4' must be one of explicit, average"),
    ({'dt': 1e-300}, f'dt (1e-300) must be a finite number of seconds, at least {MIN_DT_S:g}'),
    ({'dt': float('nan')}, 'dt (nan) must be a finite number'),
    ({'transition_s': -1.0}, 'transition_s (-1.0) must be a finite number of seconds'),
    ({'max_modes': 0}, 'max_modes (0) must be at least 1'),
    ({'tolerance': 1.5}, 'tolerance (1.5) must be between 0 and 1'),
    ({'force_refresh': -2}, 'force_refresh (-2) must be at least 1 step'),
    ({'auto': True, 'method': 'full'}, 'auto chooses modes: it needs method modal'),
    ({'forces': 'fast'}, "forces 'fast' must be one of exact, refreshed, sampled"),
    ({'anchor': 'joystick'}, "anchor 'joystick' must be one of scene, topic"),
    ({'follow_hz': 0.0}, 'follow_hz (0.0) must be a number of Hz above 0 and at most 100'),
    ({'follow_hz': float('inf')}, 'follow_hz (inf) must be a number of Hz'),
    ({'horizon_s': 0.0}, 'horizon_s (0.0) must be a number of seconds above 0 and at most 86400'),
    ({'horizon_s': float('nan')}, 'horizon_s (nan) must be a number of seconds'),
])
def test_the_configuration_names_what_is_wrong(changes, message):
    with pytest.raises(ConfigError) as info:
        SimulationConfig(**changes).validate()
    assert message in str(info.value)


def test_front_ends_name_the_setting_as_their_users_write_it():
    bad = SimulationConfig(dt=1e-300)
    with pytest.raises(ConfigError, match=r'^sim\.dt \(1e-300\)'):
        bad.validate({'dt': 'sim.dt'})
    with pytest.raises(ConfigError, match=r'^--dt \(1e-300\)'):
        bad.validate({'dt': '--dt'})


def test_a_step_that_cannot_advance_time_is_refused(sheet):
    sim = build_simulation(sheet, SimulationConfig())
    with pytest.raises(ValueError, match='does not advance time'):
        sim.with_dt(1e-300)


@pytest.mark.parametrize('method', ['full', 'modal'])
def test_a_scene_too_light_to_step_names_its_masses_not_a_step(method):
    """
    Particles of 1e-300 kg: the stability limit (1e-152 s) is below any step a run takes.

    The refusal names the limit and the masses (a step nobody gave was named before); the same
    sheet at its own mass builds at ``AUTO_DT_SAFETY`` of its limit.
    """
    light = dataclasses.replace(load_scene('sheet_10x10'), default_dt=None)
    light = dataclasses.replace(light, mass=np.full_like(light.mass, 1e-300))
    with pytest.raises(ValueError, match=r'explicit stability limit \(\d.*e-15\d s\) is below '
                                         r'the shortest step .* masses are too light'):
        build_simulation(light, SimulationConfig(method=method))
    sim = build_simulation(dataclasses.replace(light, mass=load_scene('sheet_10x10').mass),
                           SimulationConfig(method='full'))
    assert sim.dt == pytest.approx(AUTO_DT_SAFETY * sim.stability_limit())


def test_a_band_unstable_at_dt_is_refused_having_computed_modes_only_up_to_the_limit():
    """
    ``sheet_32x32`` from 32 modes (to 66 Hz), dt 4 ms: the limit 1 / (pi dt) is 79.6 Hz.

    All-pass would need 256 modes; the refusal names the first computed mode past the limit and
    costs only the modes up to it.
    """
    sim = build_simulation(load_scene('sheet_32x32'), SimulationConfig(
        band=FilterBand('lowpass', 0, 5, 'hz'), dt=0.004))
    assert sim.basis.count == 32
    limit_hz = 1.0 / (math.pi * 0.004)
    with pytest.raises(UnstableStepError, match=r'sim\.dt \(0\.004 s\) is at or above') as refused:
        sim.check_band(FilterBand(), dt_name='sim.dt')
    f = sim.basis.frequencies_hz
    assert f[-1] >= limit_hz and f[-2] < 2 * limit_hz
    assert sim.basis.count < 128                   # not the 256 all-pass asks for
    first_over = f[f >= limit_hz].max()
    assert f'({first_over:.4g} Hz)' in str(refused.value)


def test_a_new_run_unstable_at_its_given_step_is_refused_before_the_modes_of_its_band():
    """
    A rebuild (``sim.dt`` set with the band all-pass) costs only the modes up to the limit.

    ``sheet_32x32`` at dt 4 ms: the limit is 79.6 Hz; all-pass would need 256 modes.
    """
    scene = load_scene('sheet_32x32')
    sim = build_simulation(scene, SimulationConfig(band=FilterBand('lowpass', 0, 5, 'hz'),
                                                   dt=0.004))
    basis = sim.basis
    assert basis.count == 32
    with pytest.raises(UnstableStepError, match=r'^sim\.dt \(0\.004 s\) is at or above'):
        rebuild(sim.model, basis, SimulationConfig(dt=0.004), 'sim.dt')
    assert basis.frequencies_hz[-1] >= 1.0 / (math.pi * 0.004)
    assert basis.count < 128
    stable = rebuild(sim.model, basis, SimulationConfig(dt=0.0005))     # all of it is stable
    assert stable.dt == 0.0005 and stable.kept_modes.size == basis.count


def test_an_unstable_band_is_refused_before_it_is_applied(sheet):
    sim = build_simulation(sheet, SimulationConfig(band=FilterBand('lowpass', 0, 20, 'hz'),
                                                   dt=0.004))
    with pytest.raises(UnstableStepError, match=r'sim\.dt \(0\.004 s\) is at or above'):
        sim.prepare_switch(FilterBand(), dt_name='sim.dt')
    assert sim.kept_modes.size == 4
    full = build_simulation(sheet, SimulationConfig(method='full'))
    with pytest.raises(BandError, match='keeps no mode'):
        full.prepare_switch(FilterBand('lowpass', 0, 1, 'hz'))

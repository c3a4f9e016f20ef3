"""The memory estimate: its terms against what the stages really hold, and the refusal."""
from __future__ import annotations

import dataclasses

from modal_spring_ros.core import factory
from modal_spring_ros.core.bases.shift_invert import ShiftInvertModes
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.memory_estimate import (estimate, factor_entries, layers_across,
                                                   MemoryLimitError, run_size)
from modal_spring_ros.core.model.definite_factor import OrderedFactor
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.scenes.sized import sized_scene
import numpy as np
import pytest


@pytest.mark.parametrize('kind, side', [('sheet', 30), ('sheet', 60), ('sheet', 100),
                                        ('block', 8), ('block', 11), ('block', 14)])
def test_factor_entries_follow_the_sparse_lu(kind, side):
    scene = sized_scene(kind, side)
    model = MassSpringModel(scene)
    factor = ShiftInvertModes(model.stiffness_free, model.mass_dof,
                              model.free_points)._factorised()
    actual = factor.nnz if isinstance(factor, OrderedFactor) else factor.L.nnz + factor.U.nnz
    size = run_size(scene, SimulationConfig())
    assert 0.8 < factor_entries(size.dof, size.particles, size.layers) / actual < 1.25


def test_layers_do_not_depend_on_how_the_object_is_turned():
    side = 50
    grid = np.stack(np.meshgrid(np.arange(side), np.arange(side)), axis=-1).reshape(-1, 2)
    flat = np.column_stack([grid, np.zeros(len(grid))]).astype(float)
    turn = np.radians(35.0)
    rotation = np.array([[np.cos(turn), -np.sin(turn), 0], [np.sin(turn), np.cos(turn), 0],
                         [0, 0, 1]])
    assert layers_across(flat, 1.0) == pytest.approx(side, rel=0.03)
    assert layers_across(flat @ rotation.T, 1.0) == pytest.approx(side, rel=0.03)


def test_the_estimate_counts_what_the_options_add():
    scene = sized_scene('sheet', 60)
    narrow = SimulationConfig(band=FilterBand('lowpass', 0, 14, 'index'), basis='rest')
    stages = dict(estimate(run_size(scene, narrow)).stages)
    assert stages['derivatives'] == 0 and stages['spring sample'] == 0
    wide = dict(estimate(run_size(scene, SimulationConfig())).stages)   # 256 modes, derivatives
    assert wide['modes'] > 5 * stages['modes'] and wide['derivatives'] > 0
    sampled = dict(estimate(run_size(scene, dataclasses.replace(narrow, forces='sampled')))
                   .stages)
    assert sampled['spring sample'] > 0
    fewer = dataclasses.replace(SimulationConfig(), max_modes=64)
    assert estimate(run_size(scene, fewer)).total < estimate(run_size(scene, SimulationConfig())
                                                             ).total


def test_a_run_that_does_not_fit_is_refused_before_any_stage(monkeypatch):
    scene = sized_scene('sheet', 60)
    need = estimate(run_size(scene, SimulationConfig())).total

    def no_model(*_, **__):
        raise AssertionError('a stage ran before the refusal')
    monkeypatch.setattr(factory, 'MassSpringModel', no_model)
    with pytest.raises(MemoryLimitError) as refused:
        factory.build_simulation(scene, SimulationConfig(), memory_available=need // 2)
    text = str(refused.value)
    assert "scene 'sheet_60'" in text and 'GiB are available' in text
    assert 'factor' in text and 'modes' in text and 'modal.max_modes' in text
    for fits in (need, None):  # fits, or not checked: it goes on to build
        with pytest.raises(AssertionError, match='a stage ran'):
            factory.build_simulation(scene, SimulationConfig(), memory_available=fits)

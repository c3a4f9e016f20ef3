"""
Sequences of equaliser changes, as a user turning the knobs sends them, on a running modal run.

Each change alone is tested where the response is (``test_filter_response``); here random
sequences of them (kinds, edge orders, gains on the output and on the loads, damping ranges)
follow each other at random intervals, with a pull now and then, on a hanging sheet and on one
a clamp turns. Each band is checked first as the node checks it (``prepare_switch``: it keeps a
mode, its modes are stable at the step), then applied; the run must stay finite and below its
strain limit (never diverge) through the whole sequence.
"""
from __future__ import annotations

from helpers import random_band, variant
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.loads.pull import make_pull
from modal_spring_ros.core.simulations.base import DivergenceError
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest

CHANGES = 30


@pytest.mark.slow
@pytest.mark.parametrize('scene', ['sheet_10x10', 'sheet_10x10_swing'])
@pytest.mark.parametrize('seed', [0, 1, 2])
def test_a_random_sequence_of_accepted_changes_never_diverges(scene, seed):
    rng = np.random.default_rng(seed)
    sim = build_simulation(load_scene(scene), SimulationConfig())
    free = sim.model.free_particles
    applied = by_load = 0
    for change in range(CHANGES):
        band = FilterBand(**random_band(rng, top_hz=50.0))
        try:
            sim.prepare_switch(band)                 # what the node checks before it answers
        except ValueError:
            continue                                 # refused: the run as it was
        sim.set_band(band)
        applied += 1
        by_load += band.acts_on == 'load' and bool(band.gains)
        if change % 4 == 1:                          # a pull of the node's defaults
            particle = int(rng.choice(free))
            point = sim.positions()[particle] + rng.uniform(-0.2, 0.2, 3) * [1, 0, 1]
            sim.start_pull(make_pull(sim.model, particle, point, 50.0, 5.0, sim.time, 0.3))
        try:
            sim.step(int(rng.integers(20, 400)))
        except DivergenceError as exc:
            pytest.fail(f'change {change} ({band.describe()}) after {applied} applied: {exc}')
        assert np.isfinite(sim.positions()).all() and np.isfinite(sim.shown_displacement()).all()
        assert sim.max_strain() < sim.strain_limit
    assert applied >= CHANGES // 2 and by_load >= 3      # the sequence did what it says


def test_a_uniform_load_gain_is_the_same_sheet_under_that_much_more_gravity():
    """
    Every mode kept, every load gained by g: the full run under g times the gravity.

    To round-off, far into large deformation.

    A gain scales what drives the object, never the springs' answer: gaining the springs'
    nonlinear part (as once) changes the stiffness about the sagging shape, and above 1 makes
    it negative (the sequences above diverged so).
    """
    db = 12.0
    g = 10.0 ** (db / 20.0)
    sheet = variant('sheet_10x10', anchor_motion=[])
    heavy = variant('sheet_10x10', anchor_motion=[], gravity=[0.0, 0.0, -9.81 * g])
    gained = build_simulation(sheet, SimulationConfig(
        band=FilterBand(gains=(f'0:100000:{db!r}',), acts_on='load')))
    full = build_simulation(heavy, SimulationConfig(method='full'))
    assert gained.kept_modes.size == gained.basis.count           # all modes: the full run
    for _ in range(5):
        gained.step(400)
        full.step(400)
        moved = np.abs(full.positions() - sheet.rest_positions).max()
        assert np.abs(gained.positions() - full.positions()).max() < 1e-9 * moved
    assert moved > 0.01 and full.max_strain() > 0.02                # well past small sag

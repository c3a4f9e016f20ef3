"""
The work model: what a run costs, modelled.

Costs are never asserted against a clock: the model is checked by its structure (what grows
with what), by its constants, and by what refreshed forces really evaluated.
"""
from __future__ import annotations

from modal_spring_ros.core.auto import work_model
from modal_spring_ros.core.auto.work_model import work_per_second
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.scenes.resources import load_scene
import pytest


def _modal(scene, modes: int, refresh: int = 1, dt: float = 1e-3):
    return build_simulation(scene, SimulationConfig(
        method='modal', basis='rest', band=FilterBand('lowpass', 0, modes, by='index'),
        forces='refreshed' if refresh > 1 else 'exact', force_refresh=refresh, dt=dt))


def test_the_model_grows_with_what_a_step_does():
    scene = load_scene('sheet_10x10')
    few, many = _modal(scene, 5), _modal(scene, 60)
    assert work_per_second(many) > work_per_second(few)
    # half the step: twice the steps per simulated second
    assert work_per_second(_modal(scene, 5, dt=5e-4)) == pytest.approx(
        2.0 * work_per_second(few))
    full = build_simulation(scene, SimulationConfig(method='full', dt=1e-3))
    expected = (work_model.STEP_US['full'] + work_model.SPRING_US['full'] * scene.n_springs
                + work_model.DOF_US * full.model.n_free_dof) / 1e-3
    assert work_per_second(full) == pytest.approx(expected)


def test_refreshed_forces_cost_what_they_evaluated():
    """Before a step, one evaluation in ``force_refresh``; after, the share that was evaluated."""
    scene = load_scene('sheet_10x10')
    exact, refreshed = _modal(scene, 20), _modal(scene, 20, refresh=8)
    assert refreshed.evaluated_share == pytest.approx(1 / 8) and exact.evaluated_share == 1.0
    assert work_per_second(refreshed) < work_per_second(exact)
    refreshed.step(400)
    forces = refreshed._forces
    assert forces.calls == 401 and 400 / 8 <= forces.evaluations <= 401   # and the reset
    assert refreshed.evaluated_share == forces.evaluations / forces.calls
    # every evaluation it made is paid for: the model moves between its two bounds
    fixed = work_per_second(refreshed)
    assert work_per_second(_modal(scene, 20, refresh=8)) <= fixed <= work_per_second(exact)

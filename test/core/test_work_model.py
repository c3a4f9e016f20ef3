"""
The work model: what a run costs, modelled.

Costs are never asserted against a clock: the model is checked by its structure (what grows
with what), by its constants, and by what refreshed forces really evaluated.
"""
from __future__ import annotations

import dataclasses

from helpers import sheet_on_a_table

from modal_spring_ros.core.auto import work_model
from modal_spring_ros.core.auto.work_model import work_per_second
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.integrators import AverageAcceleration
from modal_spring_ros.core.model.scene import Damping
from modal_spring_ros.core.simulations.full import DampingEntries, RATIO_MODES
from modal_spring_ros.scenes.files.writing import scene_to_dict
from modal_spring_ros.scenes.resources import load_scene
from modal_spring_ros.scenes.schema import scene_from_dict
from modal_spring_ros.scenes.sized import sized_scene
import numpy as np
import pytest


def _modal(scene, modes: int, refresh: int = 1, dt: float = 1e-3, integrator='explicit'):
    return build_simulation(scene, SimulationConfig(
        method='modal', basis='rest', band=FilterBand('lowpass', 0, modes, by='index'),
        forces='refreshed' if refresh > 1 else 'exact', force_refresh=refresh, dt=dt,
        integrator=integrator))


def test_the_model_grows_with_what_a_step_does():
    scene = load_scene('sheet_10x10')
    few, many = _modal(scene, 5), _modal(scene, 60)
    assert work_per_second(many) > work_per_second(few)
    # half the step: twice the steps per simulated second
    assert work_per_second(_modal(scene, 5, dt=5e-4)) == pytest.approx(
        2.0 * work_per_second(few))
    full = build_simulation(scene, SimulationConfig(method='full', dt=1e-3))
    expected = (work_model.STEP_US['full'] + work_model.SPRING_US['full'] * scene.n_springs
                + work_model.DOF_US * full.model.n_free_dof
                + work_model.DENSE_US * full.model.n_free_dof ** 2) / 1e-3   # its modal ratio
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


def _full_sheet(side: int, damping: Damping):
    scene = dataclasses.replace(sized_scene('sheet', side), damping=damping)
    return build_simulation(scene, SimulationConfig(method='full'))


def test_a_full_run_pays_for_its_damping_as_its_step_multiplies_it():
    """A modal ratio or a ``beta K`` term costs a full step more than mass-proportional damping."""
    mass = _full_sheet(18, Damping(rayleigh_alpha=1.2))
    assert mass.damping_entries == DampingEntries()
    # 612 free DOF: every mode, and one n x n matrix multiplied each step
    every = _full_sheet(18, Damping(ratio=0.02))
    n = every.model.n_free_dof
    assert every.basis.complete and every.damping_entries == DampingEntries(dense=n * n)
    every.step()
    assert every._ops._explicit_b.shape == (n, n)
    assert work_per_second(every) == pytest.approx(
        work_per_second(mass.with_dt(every.dt)) + work_model.DENSE_US * n * n / every.dt)
    # 1,104 free DOF: the lowest modes' four products and a mass-proportional term beyond
    lowest = _full_sheet(24, Damping(ratio=0.02))
    n = lowest.model.n_free_dof
    assert not lowest.basis.complete
    assert lowest.damping_entries == DampingEntries(low_rank=4 * n * RATIO_MODES)
    # a stiffness-proportional term: a product with K and a solve with the factor, per step
    stiff = _full_sheet(18, Damping(rayleigh_alpha=1.2, rayleigh_beta=1e-5))
    k = stiff.model.stiffness_free
    assert stiff.damping_entries == DampingEntries(stiffness=k.nnz)
    ratio_stiff = _full_sheet(24, Damping(ratio=0.02, rayleigh_beta=1e-5))
    assert ratio_stiff.damping_entries == DampingEntries(
        low_rank=4 * n * RATIO_MODES, stiffness=ratio_stiff.model.stiffness_free.nnz)
    assert (work_per_second(mass) < work_per_second(stiff.with_dt(mass.dt))
            and work_per_second(mass) < work_per_second(every.with_dt(mass.dt)))


def _turning_sheet(side: int):
    spec = scene_to_dict(dataclasses.replace(sized_scene('sheet', side),
                                             damping=Damping(ratio=0.02)))
    spec['anchor_motion'] = [{'rotation': 'y', 'amplitude_deg': 30.0, 'frequency_hz': 0.5,
                              'pivot': [0.0, 0.0, 0.0]}]
    return build_simulation(scene_from_dict(spec), SimulationConfig(method='full'))


def test_a_turning_clamp_s_full_run_pays_for_damping_its_frame_s_velocity_too():
    """A turning clamp's world frame damps its own velocity too: one more product with C."""
    turning = _turning_sheet(18)
    n = turning.model.n_free_dof
    assert turning.model.rotates and turning.damping_entries == DampingEntries(dense=2 * n * n)
    # C v as the modes damp it: in one product with C = M Phi diag(c) Phi^T M once that pays
    ops, v = turning._ops, np.random.default_rng(0).standard_normal(n)
    phi, c, _ = ops._modal
    exact = ops.m * (phi @ (c * (phi.T @ (ops.m * v))))
    turning.step(n)
    assert ops._damping_matrix.shape == (n, n) and np.allclose(ops.damp(v), exact)
    assert _full_sheet(18, Damping(ratio=0.02))._ops._damping_matrix is None   # set once
    lowest = _turning_sheet(24)
    assert lowest.damping_entries == DampingEntries(
        low_rank=6 * lowest.model.n_free_dof * RATIO_MODES)


def test_an_implicit_step_pays_for_each_force_evaluation_of_its_iteration():
    """Average acceleration iterates: priced at its guess, then at the evaluations it made."""
    scene = load_scene('sheet_32x32')
    explicit, average = _modal(scene, 30), _modal(scene, 30, integrator='average')
    fixed = work_model.STEP_US['modal'] + work_model.COORDINATE_US * explicit.coordinates

    def evaluation_share(sim) -> float:   # per step, over an explicit step's
        return (work_per_second(sim) * 1e-3 - fixed) / (work_per_second(explicit) * 1e-3 - fixed)
    assert explicit.evaluations_per_step == 1.0
    assert evaluation_share(average) == pytest.approx(AverageAcceleration.evaluations_per_step)
    made = 0
    for _ in range(60):
        average.step()
        made += average.last_iterations
    assert made > 60 and average.evaluations_per_step == made / 60
    assert evaluation_share(average) == pytest.approx(made / 60)
    explicit.step(60)
    assert explicit.evaluations_per_step == 1.0
    average.reset()
    assert average.evaluations_per_step == AverageAcceleration.evaluations_per_step


def _on_a_table(colliders: int):
    """sheet_10x10 over a table, with ``colliders - 1`` spheres well away from it beside."""
    return sheet_on_a_table(*({'shape': 'sphere', 'center': [5.0 + i, 0.0, 0.0], 'radius': 0.1}
                              for i in range(colliders - 1)))


def test_a_step_pays_for_its_contact_per_collider_and_per_particle_each_measures():
    bare = load_scene('sheet_10x10')
    full = build_simulation(bare, SimulationConfig(method='full', dt=1e-3))
    free = full.model.free_particles.size
    for colliders in (1, 3):
        touching = build_simulation(_on_a_table(colliders),
                                    SimulationConfig(method='full', dt=1e-3))
        expected = (work_model.CONTACT_US + work_model.CONTACT_PARTICLE_US * free
                    + colliders * (work_model.COLLIDER_US + work_model.COLLIDER_PARTICLE_US
                                   * free))
        assert (work_per_second(touching) - work_per_second(full)) * 1e-3 == pytest.approx(
            expected)
    # a modal step also takes the positions from its coordinates and projects the touches
    modal, bare_modal = _modal(_on_a_table(1), 5), _modal(bare, 5)
    extra = (work_per_second(modal) - work_per_second(bare_modal)) * 1e-3
    assert extra == pytest.approx(work_model.contact_work(modal.model, 'full')
                                  + work_model.MODAL_CONTACT_US)

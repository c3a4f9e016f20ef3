"""
The quadratic bending of a flat surface: its forces, its runs, and how scenes keep it.

A small irregular cloth hanging from its top edge, stiff enough in bending (1e-3 N m) that its
bending carries a good share of its low modes; every figure is measured in the test.
"""
from __future__ import annotations

import dataclasses

from helpers import cloth_mesh, write_obj
from modal_spring_ros.core.bases.basis import ModalBasis
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.forces.exact import ExactForces
from modal_spring_ros.core.forces.refreshed import RefreshedForces
from modal_spring_ros.core.forces.sampled import SampledForces
from modal_spring_ros.core.forces.sampling import SpringSample
from modal_spring_ros.core.model.bending import flat_surface_bending, is_flat
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.model.scene import Damping, SceneError
from modal_spring_ros.core.motion.anchor_motion import (AnchorMotion, RotationComponent,
                                                        SineComponent)
from modal_spring_ros.core.simulations import FullSimulation, ModalSettings, ModalSimulation
from modal_spring_ros.runs import comparison
from modal_spring_ros.scenes.files.scene_archive import scene_from_archive, scene_to_archive
from modal_spring_ros.scenes.files.writing import scene_to_dict
from modal_spring_ros.scenes.schema import scene_from_dict
import numpy as np
import pytest

BENDING = 1e-3


def cloth(tmp_path, count: int = 6, stiffness: float = BENDING, **changes):
    """
    Return a 0.5 m cloth of ``count`` x ``count`` vertices hanging from its top edge.

    ``stiffness``: its bending stiffness, N m.
    """
    vertices, faces = cloth_mesh(count)
    definition = {
        'dimension': 3,
        'mesh': {'file': str(write_obj(tmp_path / f'c{count}.obj', vertices, faces)),
                 'kind': 'surface'},
        'material': {'density': 0.2, 'stiffness': 400.0, 'bending': stiffness},
        'fixed': {'box': {'min': [-1, -1, -0.001], 'max': [1, 1, 0.001]}},
        'gravity': [0.0, 0.0, -9.81], 'damping': {'rayleigh': {'alpha': 0.2}}}
    definition.update(changes)
    return scene_from_dict(definition)


def test_bending_vanishes_on_rigid_motions_and_its_stiffness_is_the_forces_derivative(tmp_path):
    scene = cloth(tmp_path)
    assert scene.loaded and scene.bending.count > 0
    flat = scene.unloaded_positions
    assert is_flat(flat)
    # zero on the shape as built, turned and moved anyhow; not on it bent into a cylinder
    turn = np.linalg.qr(np.random.default_rng(2).standard_normal((3, 3)))[0]
    size = np.abs(scene.bending.weights).sum(axis=1) * 0.5
    assert np.max(scene.bending.residual(flat @ turn.T + [3.0, -1.0, 2.0]) / size) < 1e-12
    bent = flat + np.outer(flat[:, 0] ** 2, [0.0, 1.0, 0.0])
    assert np.median(scene.bending.residual(bent) / size) > 1e-3
    # about the loaded shape, the tangent is minus the derivative of springs plus bending
    model = MassSpringModel(scene)
    forces = ExactForces(model, None)
    probe = np.random.default_rng(0).standard_normal(model.n_free_dof)
    eps = 1e-7
    numeric = (forces.elastic_forces(eps * probe) - forces.elastic_forces(-eps * probe)) / (
        2 * eps)
    np.testing.assert_allclose(-numeric, model.stiffness_free @ probe,
                               atol=1e-6 * np.max(np.abs(numeric)))
    # and the bending is in it: without, the same shape is softer
    softer = MassSpringModel(dataclasses.replace(scene, bending=None))
    assert probe @ (softer.stiffness_free @ probe) < probe @ (model.stiffness_free @ probe)
    # the loaded shape is an equilibrium of springs, bending and weight
    residual = model.free_force(np.zeros(model.n_free_dof), 0.0)
    assert np.max(np.abs(residual)) <= 1e-7 * np.max(np.abs(model.gravity_force))


def test_every_mode_with_bending_equals_the_full_physical_run(tmp_path):
    """Shaken across its plane, every mode against the full run: equal to round-off over 1 s."""
    scene = cloth(tmp_path, anchor_motion=[
        {'axis': 'y', 'amplitude': 0.02, 'frequency_hz': 1.5, 'ramp_s': 0.2}])
    model = MassSpringModel(scene)
    basis = ModalBasis(model)
    modal = ModalSimulation(model, basis, FilterBand(), ModalSettings(dt=2e-4))
    full = FullSimulation(model, dt=2e-4, basis=basis)
    worst = 0.0
    for _ in range(25):
        modal.step(200)
        full.step(200)
        u = full.displacement()
        worst = max(worst, np.linalg.norm(modal.displacement() - u) / np.linalg.norm(u))
    assert worst < 1e-8
    assert np.linalg.norm(full.displacement(), np.inf) > 1e-3      # it did move


def test_undamped_energy_with_bending_is_conserved(tmp_path):
    scene = dataclasses.replace(cloth(tmp_path), damping=Damping())
    model = MassSpringModel(scene)
    basis = ModalBasis(model)
    basis.ensure_count(6)
    sim = FullSimulation(model, dt=2e-4, basis=basis)
    start = basis.vectors[:, :6] @ np.linspace(1.0, 0.5, 6)
    at_rest = sim.energy()['total']
    sim.set_state(0.002 * start / np.max(np.abs(start)), np.zeros_like(start))
    e0 = sim.energy()
    drift, peak = 0.0, 0.0
    for _ in range(100):                        # 100 x 50 steps = 1 s
        sim.step(50)
        e = sim.energy()
        drift = max(drift, abs(e['total'] - e0['total']))
        peak = max(peak, e['kinetic'])
    assert peak > 0.5 * (e0['total'] - at_rest) > 0.0          # it swings
    assert drift < 5e-4 * peak                  # measured 5e-5 (1e-3 without bending)


def test_a_recorded_runs_energy_counts_the_bending(tmp_path):
    """What ``modal_spring_compare`` reports as a run's energy is the model's, bending included."""
    scene = cloth(tmp_path, reference='rest')
    model = MassSpringModel(scene)
    flat = scene.rest_positions
    bent = flat + np.outer((flat[:, 2] + 0.5) ** 2, [0.0, 0.2, 0.0])   # 0 at the clamped edge
    frames = np.repeat(bent[None], 3, axis=0)
    recorded = comparison.energy(comparison.RunData('bent', np.array([0.0, 0.1, 0.2]), frames,
                                                    scene, None))
    expected = model.energy(bent, np.zeros(model.n_free_dof))
    np.testing.assert_allclose(recorded, expected['total'], rtol=1e-12)
    assert model.energy(bent, np.zeros(model.n_free_dof))['spring'] > model.energy(
        bent, np.zeros(model.n_free_dof))['spring'] - 0.5 * np.sum(
        scene.bending.residual(bent) ** 2) > 0.0               # bending is a part of it


def test_a_turning_clamp_with_bending_in_its_frame_converges_to_the_full_run_in_the_world(
        tmp_path):
    """The bending's pull of the turned clamp: every mode in its frame against the world's run."""
    scene = cloth(tmp_path)
    scene = dataclasses.replace(scene, anchor_motion=AnchorMotion(
        (SineComponent(0, 0.01, 1.0, 0.2, 0.0),),
        (RotationComponent(2, 0.3, 0.8, (0.0, 0.0, 0.0), 0.2, 0.0),)))
    model = MassSpringModel(scene)
    assert model.rotates
    basis = ModalBasis(model)
    errors = []
    for dt in (4e-4, 2e-4):
        framed = ModalSimulation(model, basis, FilterBand(), ModalSettings(dt=dt))
        world = FullSimulation(model, basis, dt=dt)
        num = den = 0.0
        for _ in range(int(round(0.5 / dt))):
            framed.step()
            world.step()
            d = framed.displacement() - world.displacement()
            num += float(d @ d)
            den += float(world.displacement() @ world.displacement())
        errors.append(np.sqrt(num / den))
    assert errors[1] < 5e-3, errors
    assert errors[1] < 0.7 * errors[0], errors           # falls with the step


def test_sampled_and_refreshed_forces_take_the_bending_exactly(tmp_path):
    """
    The bending is linear: every force model adds it exactly, whatever it does with the springs.

    A sample of every spring at weight 1 is the exact spring force, so sampled forces must be
    the exact total; refreshed forces continue along a tangent that holds the bending.
    """
    model = MassSpringModel(cloth(tmp_path))
    basis = ModalBasis(model)
    basis.ensure_count(12)
    phi = basis.vectors[:, :12]
    exact = ExactForces(model, phi)
    every = SpringSample(np.arange(exact.n_springs), np.ones(exact.n_springs), 0.0, 0.0, 0.0)
    sampled = SampledForces(exact, every, tolerance=0.5)
    refreshed = RefreshedForces(exact, basis.omega[:12] ** 2, 10, 1e-3)
    q = 1e-7 * np.random.default_rng(3).standard_normal(12)   # about 1 um: linear
    total = exact(q, 0.0)
    bending = exact.add_bending(np.zeros(12), q)
    assert np.linalg.norm(bending) > 1e-3 * np.linalg.norm(total)   # a model without it fails
    np.testing.assert_allclose(sampled(q, 0.0), total, rtol=1e-10, atol=1e-14)
    refreshed(np.zeros(12), 0.0)                        # an evaluation, then continued
    continued = refreshed(q, 1e-3)
    assert np.linalg.norm(continued - total) < 1e-3 * np.linalg.norm(total - exact(0 * q, 0.0))


def test_a_scene_keeps_its_bending_in_files_and_archives(tmp_path):
    scene = cloth(tmp_path)
    for again in (scene_from_dict(scene_to_dict(scene)),
                  scene_from_archive(scene_to_archive(scene), 'archive')):
        np.testing.assert_array_equal(again.bending.hinges, scene.bending.hinges)
        np.testing.assert_array_equal(again.bending.weights, scene.bending.weights)
        np.testing.assert_allclose(again.rest_positions, scene.rest_positions, atol=1e-12)


def test_the_built_bending_is_the_written_one(tmp_path):
    """A listed scene's bending is what ``flat_surface_bending`` gives for its triangles."""
    scene = cloth(tmp_path, reference='rest')
    built = flat_surface_bending(scene.rest_positions, scene.triangles, BENDING)
    np.testing.assert_allclose(built.weights, scene.bending.weights, rtol=1e-12)


@pytest.mark.parametrize('change, problem', [
    (lambda b: {'hinges': b['hinges']}, r'bending\.weights: missing'),
    (lambda b: {**b, 'hinges': [[0, 1, 2]] * len(b['hinges'])}, 'rows of four particle'),
    (lambda b: {**b, 'hinges': [[0, 1, 2, 10 ** 6]] + b['hinges'][1:]}, 'out of range'),
    (lambda b: {**b, 'hinges': [[0, 1, 1, 2]] + b['hinges'][1:]}, 'names a particle twice'),
    (lambda b: {**b, 'weights': b['weights'][1:]}, 'rows for'),
    (lambda b: {**b, 'weights': [[1.0, 0.0, 0.0, 0.0]] + b['weights'][1:]},
     r'weights\[0\]: does not vanish on the shape as built'),
    (lambda b: {**b, 'weights': [[float('nan')] * 4] + b['weights'][1:]}, 'finite'),
    (lambda b: {**b, 'stiffness': 1.0}, 'unknown key'),
])
def test_bad_bending_in_a_scene_file_is_refused_in_one_line(tmp_path, change, problem):
    definition = scene_to_dict(cloth(tmp_path, reference='rest'))
    definition['bending'] = change(definition['bending'])
    with pytest.raises(SceneError, match=problem) as error:
        scene_from_dict(definition)
    assert '\n' not in str(error.value)


def test_a_mesh_scene_does_not_take_listed_bending(tmp_path):
    with pytest.raises(SceneError, match='bending: a mesh scene takes'):
        cloth(tmp_path, reference='rest', bending={'hinges': [], 'weights': []})


def test_a_cloth_written_to_six_decimals_is_still_flat_and_bends_as_one(tmp_path):
    """A mesh file's rounding leaves a cloth off its plane by 1e-6 of its size: flattened."""
    vertices, faces = cloth_mesh(6)
    rough = vertices + [0.0, 1e-6, 0.0] * np.random.default_rng(4).uniform(-1, 1, (36, 1))
    path = write_obj(tmp_path / 'rough.obj', np.round(rough, 6), faces)
    again = scene_from_dict({
        'dimension': 3, 'reference': 'rest', 'mesh': {'file': str(path), 'kind': 'surface'},
        'material': {'density': 0.2, 'stiffness': 400.0, 'bending': BENDING},
        'fixed': {'box': {'min': [-1, -1, -0.001], 'max': [1, 1, 0.001]}}})
    assert again.bending is not None and is_flat(again.rest_positions)
    assert np.max(np.abs(again.rest_positions - np.round(rough, 6))) < 2e-6
    assert np.max(again.bending.residual(again.rest_positions)) < 1e-12

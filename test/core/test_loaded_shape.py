"""Modes about the loaded shape: a hanging cloth or cable, slack as built, stiff as it hangs."""
from __future__ import annotations

import dataclasses

from helpers import cloth_mesh, write_obj
from modal_spring_ros.core.bases.basis import ModalBasis
from modal_spring_ros.core.bases.derivatives import tangent_derivative
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.forces.exact import ExactForces
from modal_spring_ros.core.model import loaded_shape
from modal_spring_ros.core.model.definite_factor import negative_pivots
from modal_spring_ros.core.model.loaded_shape import needs_loaded_shape
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.model.scene import Damping, SceneError
from modal_spring_ros.core.motion.anchor_motion import AnchorMotion
from modal_spring_ros.scenes.resources import load_scene
from modal_spring_ros.scenes.schema import scene_from_dict
import numpy as np
import pytest

G = 9.81


def pendulum(k: float = 50.0, m: float = 0.2, length: float = 0.5, **changes):
    scene = {'dimension': 3, 'particles': {'positions': [[0, 0, 0], [0, 0, -length]],
                                           'mass': m},
             'springs': {'pairs': [[0, 1]], 'stiffness': k}, 'fixed': {'indices': [0]},
             'gravity': [0.0, 0.0, -G]}
    scene.update(changes)
    return scene_from_dict(scene)


def hanging_cloth(count: int = 6, **changes):
    """Return a flat sheet in 3D hanging from the two corners of its top edge."""
    scene = {'dimension': 3,
             'particles': {'lattice': {'counts': [count, 1, count], 'spacing': 0.05},
                           'mass': 0.002},
             'springs': {'connect': ['edges', 'diagonals'], 'stiffness': 50.0},
             'fixed': {'indices': [count * count - count, count * count - 1]},
             'gravity': [0.0, 0.0, -G], 'damping': {'rayleigh': {'alpha': 0.0}}}
    scene.update(changes)
    return scene_from_dict(scene)


def test_a_spring_pendulum_swings_at_g_over_its_stretched_length():
    """Analytic: stretched by m g / k, it swings at g / L across and k / m along itself."""
    k, m, length = 50.0, 0.2, 0.5
    scene = pendulum(k, m, length)
    assert scene.loaded
    stretched = length + m * G / k
    np.testing.assert_allclose(scene.rest_positions[1], [0, 0, -stretched], atol=1e-9)
    basis = ModalBasis(MassSpringModel(scene))
    basis.ensure_count(3)
    np.testing.assert_allclose(basis.omega ** 2, [G / stretched, G / stretched, k / m],
                               rtol=1e-9)


def test_a_flat_cloth_in_3d_hangs_in_equilibrium_with_a_definite_tangent():
    scene = hanging_cloth()
    assert scene.loaded and needs_loaded_shape(scene_from_dict({
        'dimension': 3, 'reference': 'rest',
        'particles': {'lattice': {'counts': [3, 1, 3], 'spacing': 0.1}, 'mass': 0.01},
        'springs': {'connect': ['edges', 'diagonals'], 'stiffness': 10.0},
        'fixed': {'indices': [6, 8]}, 'gravity': [0, 0, -G]}))
    model = MassSpringModel(scene)
    weight = float(np.max(np.abs(model.gravity_force)))
    residual = model.free_force(np.zeros(model.n_free_dof), 0.0)
    assert np.max(np.abs(residual)) <= 1e-7 * weight               # an equilibrium
    # the tangent is the forces' derivative (material and geometric stiffness)
    forces = ExactForces(model, None)
    eps = 1e-7
    probe = np.random.default_rng(0).standard_normal(model.n_free_dof)
    numeric = (forces.spring_forces(eps * probe) - forces.spring_forces(-eps * probe)) / (2 * eps)
    np.testing.assert_allclose(-numeric, model.stiffness_free @ probe,
                               atol=1e-5 * np.max(np.abs(numeric)))
    basis = ModalBasis(MassSpringModel(scene))
    basis.ensure_count(4)
    assert basis.omega[0] > 0.0                                    # no mechanism left


def test_the_lowest_frequency_about_the_loaded_shape_is_the_full_runs():
    """A small swing along mode 1 in the full nonlinear run keeps mode 1's period (2 %)."""
    scene = hanging_cloth()
    sim = build_simulation(scene, SimulationConfig(method='full', integrator='explicit'))
    basis = sim.basis
    basis.ensure_count(1)
    period = 1.0 / float(basis.frequencies_hz[0])
    sim.reset()
    sim._u = 1e-5 * basis.vectors[:, 0] / np.max(np.abs(basis.vectors[:, 0]))
    along = []
    steps = int(round(2.5 * period / sim.dt))
    for _ in range(steps):
        sim.step()
        along.append(float(basis.vectors[:, 0] @ (sim.model.mass_dof * sim.displacement())))
    along = np.array(along)
    crossings = np.flatnonzero(np.diff(np.sign(along)) != 0)
    measured = 2.0 * float(np.mean(np.diff(crossings))) * sim.dt
    assert measured == pytest.approx(period, rel=0.02)


def test_the_derivative_of_the_tangent_about_the_loaded_shape():
    """Modal derivatives need ``dK/du`` where the springs are stretched: finite differences."""
    scene = hanging_cloth(4)
    model = MassSpringModel(scene)
    forces = ExactForces(model, None)
    rng = np.random.default_rng(1)
    a, b = rng.standard_normal((2, model.n_free_dof))
    eps = 1e-6
    numeric = (forces.tangent(eps * b) - forces.tangent(-eps * b)) @ a / (2 * eps)
    analytic = tangent_derivative(model, a[:, None], b[:, None])[:, 0]
    np.testing.assert_allclose(analytic, numeric, atol=1e-5 * np.max(np.abs(numeric)))


def test_no_loaded_shape_without_gravity_and_a_slack_scene_at_rest_is_a_mechanism():
    with pytest.raises(SceneError, match='reference: .*needs gravity'):
        hanging_cloth(reference='loaded', gravity=[0.0, 0.0, 0.0])
    with pytest.raises(SceneError, match='zero-stiffness mode') as held:
        ModalBasis(MassSpringModel(hanging_cloth(reference='rest'))).ensure_count(4)
    assert 'no gravity' not in str(held.value)       # it has gravity: taken at rest, asked
    # a flat cloth with no gravity at all: the error names the fix
    with pytest.raises(SceneError, match=r'no gravity: a cloth .* give it gravity \(e\.g\. '
                                         r'gravity: \[0, 0, -9\.81\]\)'):
        ModalBasis(MassSpringModel(hanging_cloth(reference='rest', gravity=[0.0, 0.0, 0.0])))


@pytest.mark.slow
def test_the_built_in_cloth_oscillates_at_its_loaded_shape_frequencies():
    """
    The lowest five frequencies about ``cloth_3d``'s loaded shape are its full run's (2 %).

    Undamped and unshaken, the full nonlinear run is started along those five modes and run
    for 20 s; the peak of each mode's share of the motion (mass-weighted projection, Hann
    window) is that mode's measured frequency. The start is small (10 um): the cloth's slack
    regions (its bottom edge, the fold between the corners) make it nonlinear from about
    0.1 mm, where the fourth frequency already moves by 2 %.
    """
    scene = dataclasses.replace(load_scene('cloth_3d'), anchor_motion=AnchorMotion(()),
                                damping=Damping())
    sim = build_simulation(scene, SimulationConfig(method='full'))
    sim.basis.ensure_count(5)
    shapes, expected = sim.basis.vectors[:, :5], sim.basis.frequencies_hz[:5]
    sim = sim.with_dt(0.9 * sim.stability_limit())
    start = shapes @ np.linspace(1.0, 0.6, 5)
    sim.set_state(1e-5 * start / np.max(np.abs(start)), np.zeros_like(start))
    every = 25
    samples = int(round(20.0 / (every * sim.dt)))
    shares = np.empty((samples, 5))
    for k in range(samples):
        sim.step(every)
        shares[k] = shapes.T @ (sim.model.mass_dof * sim.displacement())
    padded = 16 * samples
    spectra = np.abs(np.fft.rfft((shares - shares.mean(axis=0)) * np.hanning(samples)[:, None],
                                 padded, axis=0))
    measured = np.fft.rfftfreq(padded, every * sim.dt)[np.argmax(spectra, axis=0)]
    np.testing.assert_allclose(measured, expected, rtol=0.02)
    assert np.all(np.diff(measured) > 0.0)                         # five distinct peaks


def corner_cloth(tmp_path, count: int = 8):
    """Return the definition of a mesh cloth hanging from the two corners of its top edge."""
    vertices, faces = cloth_mesh(count)
    return {'dimension': 3,
            'mesh': {'file': str(write_obj(tmp_path / 'c.obj', vertices, faces)),
                     'kind': 'surface'},
            'material': {'density': 0.2, 'stiffness': 400.0, 'bending': 1e-4},
            'fixed': {'near': [{'point': [0.0, 0.0, 0.0], 'radius': 1e-3},
                               {'point': [0.5, 0.0, 0.0], 'radius': 1e-3}]},
            'gravity': [0.0, 0.0, -G]}


def test_a_large_tangent_is_checked_for_buckling_by_its_factor_alike(monkeypatch):
    """
    The sparse check (negative pivots, then modes just below zero) finds what dense eigh does.

    A lattice cloth held by two corners, without bending, buckles as it settles: equilibria the
    search leaves along their buckling modes. Checked the sparse way, it hangs in the same shape
    (or its mirror image: the same spectrum), with a definite tangent.
    """
    dense = hanging_cloth()
    counted = []

    def counting(matrix, **kwargs):
        counted.append(negative_pivots(matrix, **kwargs))
        return counted[-1]
    monkeypatch.setattr(loaded_shape, 'DENSE_LIMIT', 0)
    monkeypatch.setattr(loaded_shape, 'negative_pivots', counting)
    sparse = hanging_cloth()
    assert counted[-1] == 0 and max(counted) > 0          # it buckled, and ends definite
    spectra = []
    for scene in (dense, sparse):
        basis = ModalBasis(MassSpringModel(scene))
        basis.ensure_count(4)
        spectra.append(basis.frequencies_hz[:4])
    np.testing.assert_allclose(spectra[1], spectra[0], rtol=1e-6)


def test_a_search_at_the_round_off_of_its_forces_ends_there(tmp_path, monkeypatch):
    """With a tolerance no force can meet, the search ends when its force stops falling."""
    monkeypatch.setattr(loaded_shape, 'FORCE_RTOL', 1e-30)
    scene = scene_from_dict(corner_cloth(tmp_path))
    model = MassSpringModel(scene)
    left = np.max(np.abs(model.free_force(np.zeros(model.n_free_dof), 0.0)))
    assert 0.0 < left <= loaded_shape.STALLED_RTOL * np.max(np.abs(model.gravity_force))


def test_a_tangent_too_large_to_factor_is_one_clear_refusal_and_slow_steps_are_announced(
        monkeypatch):
    """Out of memory in the factor (a million-vertex mesh): the scene is refused in one line."""
    def no_memory(*args, **kwargs):
        raise MemoryError('Not enough memory to perform factorization.')
    monkeypatch.setattr(loaded_shape, 'factor_definite', no_memory)
    with pytest.raises(SceneError, match=r"reference: scene '.*': finding the shape it hangs in "
                                         r'\(a sparse factor of 102 coordinates\) needs more '
                                         r"memory .* 'reference: rest'"):
        hanging_cloth()                    # 36 particles, 2 held: 34 free, 3 coordinates each
    monkeypatch.undo()


def test_a_mesh_scene_says_what_it_reads_builds_and_how_long_a_step_of_its_search_takes(
        tmp_path, monkeypatch):
    monkeypatch.setattr(loaded_shape, 'SLOW_STEP_S', 0.0)   # every first step is slow here
    heard = []
    scene = scene_from_dict(corner_cloth(tmp_path), progress=heard.append)
    free = 3 * (scene.n_particles - 2)
    assert heard[2] == f'loaded shape: searching ({free:,} free coordinates)'
    assert heard[0] == f"mesh {tmp_path / 'c.obj'}: reading"
    assert heard[1] == (f"mesh {tmp_path / 'c.obj'}: 64 vertices, 98 triangles, 0 tetrahedra: "
                        'building its surface')
    assert heard[3].startswith(f'loaded shape: a step of {free:,} coordinates takes ')
    assert heard[3].endswith(f'most shapes are found in 10-30 steps (at most '
                             f'{loaded_shape.MAX_ITERATIONS})')
    assert heard[-1].startswith('loaded shape found in ')

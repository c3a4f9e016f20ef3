"""
A spring law is one module and one registry entry: every part of the engine asks it.

A toy law from the test folder (``toy_laws.StiffeningSpring``, stiffer in tension, with a
non-zero ``f''`` at rest) is registered by name alone; a scene naming it then has its forces,
energy, tangent, rest stiffness, tangent derivative, loaded shape and modes from that law,
each checked against an analytic answer or a finite difference of the law's own energy.
"""
from __future__ import annotations

import math

from modal_spring_ros.bench.peers.newton_peer import refusal
from modal_spring_ros.core import laws
from modal_spring_ros.core.bases.basis import ModalBasis
from modal_spring_ros.core.bases.derivatives import tangent_derivative
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.model.scene import SceneError
from modal_spring_ros.core.simulations.full import FullSimulation
from modal_spring_ros.core.simulations.modal import ModalSimulation
from modal_spring_ros.core.simulations.modal_settings import ModalSettings
from modal_spring_ros.scenes.files.writing import scene_to_dict
from modal_spring_ros.scenes.schema import scene_from_dict
import numpy as np
import pytest
from toy_laws import StiffeningSpring

G = 9.81


@pytest.fixture
def registered(monkeypatch):
    monkeypatch.setitem(laws.SPRING_LAWS, StiffeningSpring.name, StiffeningSpring)
    return StiffeningSpring.name


def sheet(law: str, count: int = 4, **changes):
    data = {'dimension': 2, 'plane': 'xz',
            'particles': {'lattice': {'counts': [count, count], 'spacing': 0.1},
                          'mass': 0.01},
            'springs': {'connect': ['edges', 'diagonals'], 'stiffness': 40.0},
            'fixed': {'face': '+z'}, 'spring_law': law}
    data.update(changes)
    return scene_from_dict(data)


def test_a_scene_names_its_law_and_an_unknown_one_is_refused(registered):
    scene = sheet(registered)
    assert scene.spring_law == registered
    assert MassSpringModel(scene).law.name == registered
    assert scene_from_dict(scene_to_dict(scene)).spring_law == registered   # written back
    assert 'spring_law' not in scene_to_dict(sheet('linear'))                # the default
    assert 'linear' in refusal(scene)            # the Newton peer's springs are linear only
    with pytest.raises(SceneError, match='spring_law.*must be one of linear, stiffening, '
                                         "got 'rubber'"):
        sheet('rubber')


def stretched_state(model: MassSpringModel, scale: float = 0.02, seed: int = 3):
    rng = np.random.default_rng(seed)
    return scale * rng.standard_normal(model.n_free_dof)


def test_the_force_is_minus_the_gradient_of_the_laws_energy(registered):
    model = MassSpringModel(sheet(registered))
    u = stretched_state(model)
    force = model.physical_forces.elastic_forces(u.copy())
    direction = np.random.default_rng(5).standard_normal(u.size)
    h = 1e-6

    def energy(w):
        x = model.rest.copy().ravel()
        x[model.free_dof] += w
        return model.energy(x.reshape(model.rest.shape), np.zeros(w.size))['spring']

    slope = (energy(u + h * direction) - energy(u - h * direction)) / (2 * h)
    assert slope == pytest.approx(-float(force @ direction), rel=1e-6)
    # not the linear spring's: the law really changed the force
    linear = MassSpringModel(sheet('linear')).physical_forces.elastic_forces(u.copy())
    assert np.linalg.norm(force - linear) > 0.05 * np.linalg.norm(linear)


def test_the_tangent_and_its_derivative_are_the_laws(registered):
    model = MassSpringModel(sheet(registered))
    forces = model.physical_forces
    u = stretched_state(model)
    rng = np.random.default_rng(7)
    a, b = rng.standard_normal((2, model.n_free_dof))
    h = 1e-6
    numeric = -(forces.elastic_forces(u + h * a) - forces.elastic_forces(u - h * a)) / (2 * h)
    np.testing.assert_allclose(forces.tangent(u) @ a, numeric,
                               atol=1e-6 * np.max(np.abs(numeric)))
    # at rest: the tangent is the rest stiffness, and its derivative carries f'' (non-zero)
    np.testing.assert_allclose(forces.tangent(np.zeros(u.size)), model.stiffness_free.toarray(),
                               atol=1e-9)
    numeric = (forces.tangent(h * b) - forces.tangent(-h * b)) @ a / (2 * h)
    analytic = tangent_derivative(model, a[:, None], b[:, None])[:, 0]
    np.testing.assert_allclose(analytic, numeric, atol=1e-6 * np.max(np.abs(numeric)))


def test_a_pendulum_hangs_and_swings_as_its_law_says(registered):
    """Analytic: stretched by e with ``k e (1 + e / l) = m g``; swings at g / L and f'(L) / m."""
    k, m, rest = 50.0, 0.2, 0.5
    scene = scene_from_dict({
        'dimension': 3, 'particles': {'positions': [[0, 0, 0], [0, 0, -rest]], 'mass': m},
        'springs': {'pairs': [[0, 1]], 'stiffness': k}, 'fixed': {'indices': [0]},
        'gravity': [0.0, 0.0, -G], 'spring_law': registered})
    assert scene.loaded
    e = (-rest + math.sqrt(rest * rest + 4.0 * rest * m * G / k)) / 2.0   # k e + k e^2 / l = m g
    np.testing.assert_allclose(scene.rest_positions[1], [0, 0, -(rest + e)], atol=1e-9)
    basis = ModalBasis(MassSpringModel(scene))
    basis.ensure_count(3)
    along = k * (1.0 + 2.0 * e / rest) / m
    np.testing.assert_allclose(basis.omega ** 2, [G / (rest + e), G / (rest + e), along],
                               rtol=1e-9)


def test_runs_keep_the_laws_energy_and_every_mode_is_the_full_run(registered):
    model = MassSpringModel(sheet(registered))
    basis = ModalBasis(model)
    runs = {'modal': ModalSimulation(model, basis, FilterBand(), ModalSettings(dt=2e-4)),
            'full': FullSimulation(model, dt=2e-4, basis=basis)}
    u0 = stretched_state(model, 0.01)
    for sim in runs.values():
        sim.set_state(u0, np.zeros(u0.size))
    start = runs['full'].energy()['total']
    for sim in runs.values():
        sim.step(2000)                                       # 0.4 s, undamped
        assert sim.energy()['total'] == pytest.approx(start, rel=2e-3)
    full = runs['full'].displacement()
    np.testing.assert_allclose(runs['modal'].displacement(), full,
                               atol=1e-8 * np.max(np.abs(full)))

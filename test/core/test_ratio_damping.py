"""
A modal damping ratio on a scene too large for every mode: the full run and auto alike.

The full run damps the lowest ``RATIO_MODES`` modes exactly by the ratio and the rest by the
mass-proportional term that matches it at the highest of them (docs/method.md). On a scene
small enough for every mode, that run is checked against the exact modal damping.
"""
from __future__ import annotations

from helpers import variant
from modal_spring_ros.core.auto.measured_error import trajectory, trajectory_error
from modal_spring_ros.core.bases.basis import ModalBasis
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.simulations import FullSimulation
from modal_spring_ros.core.simulations.full import PhysicalOperators, RATIO_MODES
import numpy as np
import pytest

RATIO = 0.02


def _bases(scene):
    model = MassSpringModel(scene)
    return model, ModalBasis(model, dense_limit=10**6), ModalBasis(model, dense_limit=0)


def test_the_lowest_modes_get_the_ratio_and_the_rest_the_matched_mass_term():
    scene = variant('sheet_10x10',
                    damping={'ratio': RATIO, 'rayleigh': {'alpha': 0.3, 'beta': 1e-5}})
    model, exact, partial = _bases(scene)
    assert exact.complete and not partial.complete
    ops = PhysicalOperators(model, scene.damping, 5e-4, partial)
    phi, omega = exact.vectors, exact.omega
    damped = phi.T @ np.column_stack([ops.damp(phi[:, i]) for i in range(phi.shape[1])])
    k = RATIO_MODES
    wanted = scene.damping.modal_coefficients(omega)
    # the damping of each mode in the modes' own coordinates (lumped mass: Phi^T M Phi = I)
    np.testing.assert_allclose(np.diag(damped)[:k], wanted[:k], rtol=1e-6)
    tail = 0.3 + 2.0 * RATIO * omega[k - 1] + 1e-5 * omega[k:] ** 2
    np.testing.assert_allclose(np.diag(damped)[k:], tail, rtol=1e-6)
    assert np.all(np.diag(damped)[k:] <= wanted[k:])          # never more than the ratio
    off = damped - np.diag(np.diag(damped))
    assert np.abs(off).max() <= 1e-8 * np.abs(np.diag(damped)).max()


@pytest.mark.slow
@pytest.mark.parametrize('integrator', ['explicit', 'average'])
def test_on_a_scene_small_enough_it_follows_the_exact_modal_damping(integrator):
    """sheet_10x10 at a 2 % ratio over 3 s: within 0.01 % of the exact modal damping."""
    scene = variant('sheet_10x10', damping={'ratio': RATIO})
    model, exact, partial = _bases(scene)
    runs = []
    for basis in (exact, partial):
        sim = FullSimulation(model, basis, FilterBand(), dt=1e-3, integrator=integrator)
        sim = sim.with_dt(0.45 * sim.stability_limit() if integrator == 'explicit' else 5e-4)
        runs.append(trajectory(sim, 20 * sim.dt, int(3.0 / (20 * sim.dt))))
    assert runs[1] is not None
    assert trajectory_error(runs[1], runs[0]) < 1e-4


@pytest.mark.slow
def test_a_scene_too_large_for_every_mode_runs_full_and_auto_with_a_modal_ratio():
    """sheet_32x32 (1,984 free DOF, beyond the dense limit) with a 2 % ratio: was refused."""
    scene = variant('sheet_32x32', damping={'ratio': RATIO})
    full = build_simulation(scene, SimulationConfig(method='full'))
    assert not full.basis.complete
    full.step(400)
    assert np.isfinite(full.displacement()).all() and full.max_strain() > 0.005
    auto = build_simulation(scene, SimulationConfig(auto=True))
    assert auto.pilot.against == 'the full run'
    assert auto.pilot.error <= 0.01, auto.pilot.describe()

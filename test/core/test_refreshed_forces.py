"""Reduced force evaluation: tangent stiffness, static equilibrium, springs every N steps."""
from __future__ import annotations

from modal_spring_ros.core.bases.basis import ModalBasis
from modal_spring_ros.core.bases.mode_selection import choose_refresh
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.forces import ForceOptions
from modal_spring_ros.core.forces.exact import ExactForces
from modal_spring_ros.core.forces.refreshed import RefreshedForces, static_equilibrium
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.simulations import DivergenceError, ModalSettings, ModalSimulation
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest

LOWPASS_16 = FilterBand('lowpass', 0, 15, 'index')


@pytest.fixture(scope='module')
def cantilever():
    model = MassSpringModel(load_scene('cantilever_3d'))
    return model, ModalBasis(model, initial_modes=12)


@pytest.mark.parametrize('scene', ['sheet_10x10', 'cantilever_3d'])
def test_tangent_at_rest_is_the_modal_stiffness(scene, sheet_10x10, cantilever):
    model, basis = sheet_10x10 if scene == 'sheet_10x10' else cantilever
    phi = basis.vectors[:, :12]
    tangent = ExactForces(model, phi).tangent(np.zeros(12))
    omega2 = basis.omega[:12] ** 2
    np.testing.assert_allclose(tangent, np.diag(omega2), atol=1e-10 * omega2.max())
    # in physical coordinates the tangent at rest is the assembled sparse K
    physical = ExactForces(model, None).tangent(np.zeros(model.n_free_dof), chunk=97)
    np.testing.assert_allclose(physical, model.stiffness_free.toarray(),
                               atol=1e-10 * abs(physical).max())


def test_tangent_is_the_derivative_of_the_spring_forces(sheet_10x10):
    model, basis = sheet_10x10
    forces = ExactForces(model, basis.vectors[:, :10])
    rng = np.random.default_rng(3)
    q = rng.normal(scale=0.02, size=10)          # a few % strain: far from the rest tangent
    assert forces.tangent(q, chunk=50) == pytest.approx(forces.tangent(q))  # chunking
    h = 1e-6
    numeric = np.column_stack([
        -(forces.spring_forces(q + h * e) - forces.spring_forces(q - h * e)) / (2 * h)
        for e in np.eye(10)])
    tangent = forces.tangent(q)
    np.testing.assert_allclose(tangent, numeric, atol=1e-6 * abs(tangent).max())
    assert abs(tangent - np.diag(basis.omega[:10] ** 2)).max() > 1e-3 * abs(tangent).max()


def test_static_equilibrium_balances_gravity(sheet_10x10):
    model, basis = sheet_10x10
    forces = ExactForces(model, basis.vectors[:, :16])
    q, found = static_equilibrium(forces, basis.omega[:16] ** 2)
    assert found
    residual = forces.spring_forces(q) + forces.gravity()
    assert np.linalg.norm(residual) < 1e-9 * np.linalg.norm(forces.gravity())
    assert np.linalg.norm(q) > 0.0


def test_springs_are_evaluated_every_n_steps(sheet_10x10, monkeypatch):
    model, basis = sheet_10x10
    sim = ModalSimulation(model, basis, LOWPASS_16,
                          ModalSettings(dt=1e-3, forces=ForceOptions('refreshed', 8)))
    calls = []
    original = ExactForces.spring_forces
    monkeypatch.setattr(ExactForces, 'spring_forces',
                        lambda self, q: calls.append(1) or original(self, q))
    sim.step(80)
    assert len(calls) == 10
    sim.reset()                                  # a restart evaluates at once
    assert len(calls) == 11


def test_refreshed_run_follows_the_every_step_run(sheet_10x10):
    """
    The paper's method (every step) against springs every 8 steps.

    2 s of the default scene (gravity drop, anchor sway and shake): the same run within 0.1 %.
    """
    model, basis = sheet_10x10

    def run(refresh):
        sim = ModalSimulation(model, basis, LOWPASS_16,
                              ModalSettings(dt=1e-3, forces=ForceOptions('refreshed', refresh)))
        out = []
        for _ in range(200):
            sim.step(10)
            out.append(sim.displacement())
        return np.array(out), sim

    exact, _ = run(1)
    refreshed, sim = run(8)
    assert np.linalg.norm(refreshed - exact) / np.linalg.norm(exact) < 1e-3
    assert 0.0 < sim.force_report().error < 1e-2        # measured, and reported
    assert isinstance(sim._forces, RefreshedForces) and sim._forces.static_found


def test_refreshed_undamped_energy_stays_bounded(sheet_undamped_still):
    """Holding the nonlinear part between refreshes must not pump energy into the modes."""
    model, basis = sheet_undamped_still
    sim = ModalSimulation(model, basis, LOWPASS_16,
                          ModalSettings(dt=1e-3, forces=ForceOptions('refreshed', 10)))
    e0 = sim.energy()['total']
    drift, peak_kinetic, at_10s = 0.0, 0.0, None
    for k in range(3000):                        # 3000 x 10 steps = 30 s
        sim.step(10)
        e = sim.energy()
        drift = max(drift, abs(e['total'] - e0))
        peak_kinetic = max(peak_kinetic, e['kinetic'])
        if k == 999:
            at_10s = drift / peak_kinetic
    assert peak_kinetic > 0.005
    assert at_10s < 1e-2                         # bounded (every step: about 1e-3 here)
    assert drift / peak_kinetic < 1.1 * at_10s   # and not growing


def test_refreshed_runs_are_bit_identical(sheet_10x10):
    model, basis = sheet_10x10
    runs = [ModalSimulation(model, basis, LOWPASS_16,
                            ModalSettings(dt=1e-3, forces=ForceOptions('refreshed', 5)))
            for _ in range(2)]
    for sim in runs:
        sim.step(300)
    assert np.array_equal(runs[0].positions(), runs[1].positions())


def test_band_change_with_refreshed_forces_is_smooth(sheet_10x10):
    model, basis = sheet_10x10
    sim = ModalSimulation(model, basis, LOWPASS_16,
                          ModalSettings(dt=1e-3, forces=ForceOptions('refreshed', 8)))
    sim.step(500)
    before = sim.positions()
    sim.set_band(FilterBand('lowpass', 0, 5, 'index'), transition_s=0.2)
    sim.step(1)
    assert np.abs(sim.positions() - before).max() < 1e-3
    sim.step(400)
    assert not sim.fading and sim.stepped_modes.size == 6


@pytest.mark.slow
def test_auto_chooses_the_refresh_and_an_explicit_value_wins():
    auto = build_simulation(load_scene('sheet_10x10'), SimulationConfig(auto=True))
    assert auto.force_refresh == choose_refresh(auto.mode_choice.highest_hz, auto.dt) > 1
    fixed = build_simulation(load_scene('sheet_10x10'),
                             SimulationConfig(auto=True, force_refresh=3))
    assert fixed.force_refresh == 3
    assert build_simulation(load_scene('sheet_10x10'), SimulationConfig()).force_refresh == 1
    with pytest.raises(ValueError, match='force_refresh'):
        build_simulation(load_scene('sheet_10x10'), SimulationConfig(force_refresh=-2))


def test_choose_refresh_holds_half_a_period_of_the_highest_mode():
    assert choose_refresh(50.0, 1e-3) == 10      # 0.5 / 50 Hz = 10 ms
    assert choose_refresh(50.0, 0.02) == 1       # never less than every step
    assert choose_refresh(0.01, 1e-3) == 200     # capped


@pytest.mark.parametrize('scene', ['sheet_10x10', 'cantilever_3d'])
def test_strain_sensitivity_bounds_every_springs_strain_change(scene, sheet_10x10, cantilever):
    model, basis = sheet_10x10 if scene == 'sheet_10x10' else cantilever
    forces = ExactForces(model, basis.vectors[:, :12])
    gain = forces.strain_sensitivity()

    def strains(q):
        length = np.linalg.norm(forces.spring_deltas(q), axis=0)
        return length / np.asarray(model.scene.rest_length) - 1.0

    rng = np.random.default_rng(5)
    q0 = rng.normal(scale=1e-3, size=12)
    ratios = []
    for _ in range(200):
        dq = rng.normal(size=12) * 10.0 ** rng.uniform(-6, -3)
        change = np.abs(strains(q0 + dq) - strains(q0)).max()
        assert change <= gain * np.linalg.norm(dq) * (1 + 1e-9)
        ratios.append(change / (gain * np.linalg.norm(dq)))
    # and it is the least such bound: the most sensitive spring, moved along its most
    # sensitive direction far enough that the move dominates its length, reaches it
    g = forces._g_rows(0, model.scene.springs.shape[0])          # (d, E, m)
    top = np.array([np.linalg.svd(g[:, e], compute_uv=False)[0] for e in range(g.shape[1])])
    worst = int(np.argmax(top / np.asarray(model.scene.rest_length)))
    _, _, vt = np.linalg.svd(g[:, worst])
    dq = 100.0 * np.asarray(model.scene.rest_length)[worst] / top[worst] * vt[0]
    reached = abs(strains(dq)[worst] - strains(np.zeros(12))[worst]) / (
        gain * np.linalg.norm(dq))
    assert 0.98 < reached <= 1.0 + 1e-9, (reached, max(ratios))


def test_refreshed_forces_detect_divergence_on_the_step_it_happens():
    """
    Between refreshes the strain bound stands in for the exact strain.

    The step where the strain first passes the limit is reported, as with every spring evaluated
    every step, and no accepted state is above the limit.
    """
    band = FilterBand('lowpass', 0, 14, 'index')
    free = build_simulation(load_scene('sheet_10x10'), SimulationConfig(band=band))
    history = []
    for _ in range(200):                      # released from rest under gravity: overshoot
        free.step()
        history.append(free.max_strain())
    history = np.array(history)
    limit = 0.5 * (history.max() + history[-1])
    first = int(np.argmax(history > limit)) + 1
    assert 10 < first < 190
    reported = {}
    for refresh in (1, 25):
        sim = build_simulation(load_scene('sheet_10x10'), SimulationConfig(
            band=band, force_refresh=refresh, strain_limit=limit))
        assert first % 25 != 0                # the crossing falls between two refreshes
        with pytest.raises(DivergenceError, match='spring strain .* exceeds the limit'):
            for _ in range(200):
                sim.step()
                assert sim.max_strain() <= limit
        reported[refresh] = sim.steps + 1
    assert reported[25] == reported[1] == first


def test_refreshed_forces_fall_back_to_exact_ones_past_the_tolerance():
    """
    A flag driven at its resonance: the error at a refresh grows to 50 % (0.1-0.9 % on sways).

    Past ``modal.tolerance`` every later step is exact, said in the status, and the run stays
    with the exact one where the unchecked shortcut drifts away.
    """
    scene = load_scene('sheet_32x32_resonance')
    band = FilterBand('lowpass', 0.0, 30.0)

    def run(refresh, tolerance=0.01):
        sim = build_simulation(scene, SimulationConfig(band=band, force_refresh=refresh,
                                                       tolerance=tolerance or 0.01))
        if tolerance is None:         # the shortcut unchecked, as before it checked itself
            sim = ModalSimulation(sim.model, sim.basis, band,
                                  ModalSettings(dt=sim.dt,
                                                forces=ForceOptions('refreshed', refresh)))
        out = []
        for _ in range(60):
            sim.step(int(round(0.05 / sim.dt)))
            out.append(sim.displacement())
        return np.array(out), sim

    exact, _ = run(1)
    unchecked, loose = run(10, None)
    checked, sim = run(10, 0.01)
    assert not loose.force_report().fell_back and loose.force_report().error > 0.1
    report = sim.force_report()
    assert report.fell_back and sim.status().forces.fell_back and report.interval == 1
    assert 'fell back: error' in report.description and 'beyond 1.00%' in report.description

    def error(run_):
        return np.linalg.norm(run_ - exact) / np.linalg.norm(exact)
    assert error(checked) < 0.5 * error(unchecked), (error(checked), error(unchecked))


def test_refreshed_forces_within_the_tolerance_keep_their_shortcut(sheet_10x10):
    model, basis = sheet_10x10
    sim = ModalSimulation(model, basis, LOWPASS_16,
                          ModalSettings(dt=1e-3, forces=ForceOptions('refreshed', 8, 0.01)))
    sim.step(2000)
    report = sim.force_report()
    assert 0.0 < report.error < 0.01 and not report.fell_back and report.interval == 8
    assert report.description == 'exact every 8 steps, tangent between'

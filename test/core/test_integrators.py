"""Newmark stepping: analytic oscillator, convergence order, energy, stability limits."""
from __future__ import annotations

import math

from helpers import oscillator
from modal_spring_ros.core.bases.basis import ModalBasis
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.simulations import (DivergenceError, FullSimulation, ModalSettings,
                                               ModalSimulation)
import numpy as np
import pytest


def _oscillator_run(dt: float, duration: float, integrator: str, amplitude: float = 0.01):
    model = MassSpringModel(oscillator())
    sim = FullSimulation(model, dt=dt, integrator=integrator)
    sim.set_state(np.array([amplitude]), np.array([0.0]))
    steps = int(round(duration / dt))
    xs = np.empty(steps + 1)
    xs[0] = amplitude
    for k in range(steps):
        sim.step()
        xs[k + 1] = sim.displacement()[0]
    return np.arange(steps + 1) * dt, xs


@pytest.mark.parametrize('integrator', ['explicit', 'average'])
def test_single_oscillator_matches_the_analytic_solution(integrator):
    omega = math.sqrt(400.0 / 0.25)                 # 40 rad/s
    t, x = _oscillator_run(1e-4, 2.0, integrator)
    np.testing.assert_allclose(x, 0.01 * np.cos(omega * t), atol=2e-6)
    # period from upward zero crossings, amplitude from the extremes
    crossings = t[1:][(x[:-1] < 0) & (x[1:] >= 0)]
    assert np.diff(crossings).mean() == pytest.approx(2 * math.pi / omega, rel=1e-4)
    assert np.abs(x).max() == pytest.approx(0.01, rel=1e-4)


@pytest.mark.parametrize('integrator', ['explicit', 'average'])
def test_measured_convergence_order_is_two(integrator):
    omega = 40.0
    errors = []
    for dt in (4e-3, 2e-3, 1e-3):
        t, x = _oscillator_run(dt, 1.0, integrator)
        errors.append(np.abs(x - 0.01 * np.cos(omega * t)).max())
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all((orders > 1.9) & (orders < 2.1)), orders


def test_modal_with_all_modes_equals_the_full_physical_run(sheet_10x10):
    """Same integrator, equivalent damping: equal to round-off over 2 s of sheet_10x10."""
    model, basis = sheet_10x10
    modal = ModalSimulation(model, basis, FilterBand(), ModalSettings(dt=5e-4))
    full = FullSimulation(model, dt=5e-4, basis=basis)
    worst = 0.0
    for _ in range(40):                          # 40 x 100 steps = 2 s
        modal.step(100)
        full.step(100)
        u_full = full.displacement()
        worst = max(worst, np.linalg.norm(modal.displacement() - u_full)
                    / np.linalg.norm(u_full))
    assert worst < 1e-8
    assert np.linalg.norm(full.displacement()) > 1e-3     # it did move


def test_average_acceleration_modal_equals_full_too(sheet_10x10):
    model, basis = sheet_10x10
    modal = ModalSimulation(model, basis, FilterBand(),
                            ModalSettings(dt=2e-3, integrator='average'))
    full = FullSimulation(model, dt=2e-3, integrator='average', basis=basis)
    modal.step(250)
    full.step(250)
    u = full.displacement()
    assert np.linalg.norm(modal.displacement() - u) / np.linalg.norm(u) < 1e-8


def test_undamped_energy_is_conserved_below_the_stability_limit(sheet_undamped_still):
    model, basis = sheet_undamped_still
    sim = ModalSimulation(model, basis, FilterBand(), ModalSettings(dt=5e-4))
    assert sim.dt < 0.5 * sim.stability_limit()
    e0 = sim.energy()['total']
    drift, peak_kinetic = 0.0, 0.0
    for _ in range(2000):                        # 2000 x 10 steps = 10 s
        sim.step(10)
        e = sim.energy()
        drift = max(drift, abs(e['total'] - e0))
        peak_kinetic = max(peak_kinetic, e['kinetic'])
    assert peak_kinetic > 0.005                  # the sheet dropped and swings (~8.5 mJ)
    assert drift < 1e-3 * peak_kinetic


def test_explicit_step_above_the_limit_diverges_and_is_reported(sheet_undamped_still):
    model, basis = sheet_undamped_still
    limit = 2.0 / basis.omega[-1]
    sim = FullSimulation(model, dt=1.05 * limit, basis=basis)
    with pytest.raises(DivergenceError) as err:
        sim.step(2000)
    assert 'strain' in err.value.reason or 'non-finite' in err.value.reason
    assert sim.diverged is err.value
    # the state kept is the last good one: finite, and strain within the limit
    assert np.isfinite(sim.positions()).all()
    assert sim.max_strain() <= sim.strain_limit
    # just below the limit the same run stays bounded
    stable = FullSimulation(model, dt=0.95 * limit, basis=basis)
    stable.step(2000)
    assert stable.max_strain() < 0.05


def test_modal_lowpass_is_stable_where_the_full_explicit_run_diverges(sheet_undamped_still):
    model, basis = sheet_undamped_still
    dt = 1.5 * 2.0 / basis.omega[-1]
    with pytest.raises(DivergenceError):
        FullSimulation(model, dt=dt, basis=basis).step(3000)
    modal = ModalSimulation(model, basis, FilterBand('lowpass', high=14, by='index'),
                            ModalSettings(dt=dt))
    modal.step(3000)
    assert modal.max_strain() < 0.05


@pytest.mark.parametrize('times', [10, 100, 300])
@pytest.mark.parametrize('method', ['full', 'modal'])
def test_average_acceleration_is_stable_far_beyond_the_explicit_limit(sheet_10x10, method,
                                                                      times):
    """
    From a state with every mode excited (the stability benchmark's start).

    Where the iteration's first guess decides whether it converges at all.
    """
    model, basis = sheet_10x10
    dt = times * 2.0 / basis.omega[-1]
    if method == 'full':
        sim = FullSimulation(model, dt=dt, integrator='average', basis=basis)
    else:
        sim = ModalSimulation(model, basis, FilterBand(),
                              ModalSettings(dt=dt, integrator='average'))
    u0 = basis.vectors @ np.random.default_rng(7).normal(scale=1e-4, size=basis.count)
    sim.set_state(u0, np.zeros_like(u0))
    iterations = []
    for _ in range(200):
        sim.step()
        iterations.append(sim.last_iterations)
    assert np.isfinite(sim.positions()).all() and sim.max_strain() < 0.05
    assert max(iterations) <= 8      # converges to 1e-10 in a few fixed-tangent iterations


def test_runs_are_bit_identical(sheet_10x10):
    model, basis = sheet_10x10
    a = ModalSimulation(model, basis, FilterBand('bandpass', 2, 48, 'index'),
                        ModalSettings(dt=5e-4))
    b = ModalSimulation(model, ModalBasis(model), FilterBand('bandpass', 2, 48, 'index'),
                        ModalSettings(dt=5e-4))
    a.step(500)
    b.step(500)
    assert np.array_equal(a.positions(), b.positions())

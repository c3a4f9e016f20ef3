"""
Modal derivatives with static load vectors: right beyond small deformation.

Each figure is measured against the full nonlinear run in the test itself (relative L2 error
of the displacement from the moving base), on the scenes where rest modes fail.
"""
from __future__ import annotations

import math

from helpers import max_step_motion, power_above, variant
from modal_spring_ros.core.bases import derivatives
from modal_spring_ros.core.bases.basis import ModalBasis
from modal_spring_ros.core.bases.derivatives import (added_coordinates, drive_gains,
                                                     MAX_DRIVE_GAIN, MAX_PAIR_MODES,
                                                     static_load_vectors, tangent_derivative)
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import rebuild
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.forces import ForceOptions
from modal_spring_ros.core.forces.exact import ExactForces
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.simulations import FullSimulation, ModalSettings, ModalSimulation
from modal_spring_ros.core.worker import WorkerProcess
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest

LOWPASS_0_14 = FilterBand('lowpass', 0, 14, 'index')
WINDOW_S = 0.25


@pytest.fixture(scope='module')
def resonance():
    model = MassSpringModel(load_scene('sheet_10x10_resonance'))
    return model, ModalBasis(model)


def errors_against_full(model, basis, sims: dict, duration: float, dt: float,
                        full_dt: float | None = None) -> dict:
    """
    Return each simulation's error against the full run.

    As (largest windowed error, error over the run), against the full run (stepped at
    ``full_dt``, a whole fraction of ``dt``, when that is smaller).
    """
    substeps = int(round(dt / full_dt)) if full_dt else 1
    full = FullSimulation(model, basis, dt=dt / substeps)
    window = int(round(WINDOW_S / dt))
    sums = {name: [0.0, 0.0, 0.0, 0.0, 0.0] for name in sims}
    for step in range(1, int(round(duration / dt)) + 1):
        full.step(substeps)
        f = full.displacement()
        ff = float(f @ f)
        for name, sim in sims.items():
            sim.step()
            d = sim.displacement() - f
            s = sums[name]
            dd = float(d @ d)
            s[0] += dd
            s[1] += ff
            s[2] += dd
            s[3] += ff
            if step % window == 0:
                s[4] = max(s[4], math.sqrt(s[0] / s[1]))
                s[0] = s[1] = 0.0
    return {name: (s[4], math.sqrt(s[2] / s[3])) for name, s in sums.items()}


def test_the_tangent_derivative_matches_a_central_difference(resonance):
    model, basis = resonance
    physical = ExactForces(model, None)
    eps = 1e-6
    for i, j in ((0, 0), (0, 3), (2, 7), (5, 14)):
        a, b = basis.vectors[:, i], basis.vectors[:, j]
        difference = (physical.tangent(eps * b) - physical.tangent(-eps * b)) @ a / (2 * eps)
        exact = tangent_derivative(model, a[:, None], b[:, None])[:, 0]
        assert np.linalg.norm(difference - exact) <= 1e-7 * np.linalg.norm(exact), (i, j)


def test_added_coordinates_leave_the_band_alone_and_keep_k0_diagonal(resonance):
    model, basis = resonance
    keep = np.arange(2, 49)                      # a band-pass: modes 0 and 1 removed below it
    added = added_coordinates(basis, keep, directions=15)
    assert added.count == 15 and added.derivative_count == 15   # no static load: 0 and 4.7 Hz
    #                                                     lie below the band (12.9 Hz up)
    mass = model.mass_dof
    vectors = added.vectors
    np.testing.assert_allclose(vectors.T @ (mass[:, None] * vectors), np.eye(15), atol=1e-10)
    below_and_kept = basis.vectors[:, :49]
    assert np.abs(below_and_kept.T @ (mass[:, None] * vectors)).max() < 1e-10
    stiffness = vectors.T @ (model.stiffness_free @ vectors)
    np.testing.assert_allclose(stiffness, np.diag(added.omega ** 2),
                               atol=1e-9 * added.omega.max() ** 2)
    assert added.omega.min() > basis.omega[48]   # stiff: the quasi-static response
    every = added_coordinates(basis, np.arange(basis.count))
    assert every.count == 0                      # a band of every mode has nothing to add


@pytest.mark.slow
def test_the_resonance_scene_stays_right_where_rest_modes_drift(resonance):
    """The paper's fig. 10 failure: rest modes 0..14 drift to 46 % error in a window."""
    model, basis = resonance
    sims = {kind: ModalSimulation(model, basis, LOWPASS_0_14,
                                  ModalSettings(dt=5e-4, basis_kind=kind))
            for kind in ('rest', 'derivatives')}
    errors = errors_against_full(model, basis, sims, 6.0, 5e-4)
    worst, overall = errors['derivatives']
    assert worst < 0.02 and overall < 0.01, errors
    assert errors['rest'][0] > 0.3 and errors['rest'][1] > 0.2, errors


@pytest.mark.slow
def test_small_deformation_gets_more_accurate_too():
    model = MassSpringModel(load_scene('sheet_10x10'))
    basis = ModalBasis(model)
    sims = {kind: ModalSimulation(model, basis, LOWPASS_0_14,
                                  ModalSettings(dt=5e-4, basis_kind=kind))
            for kind in ('rest', 'derivatives')}
    errors = errors_against_full(model, basis, sims, 5.0, 5e-4)
    assert errors['derivatives'][1] < 0.003, errors
    assert errors['rest'][1] > 3 * errors['derivatives'][1], errors


@pytest.mark.slow
def test_a_wider_band_with_derivatives_is_no_worse_on_the_resonance(resonance):
    """
    The clamp shakes mode 0 at resonance: its own derivative must lead every band's directions.

    Weighted by frequency alone, 24 and 32 modes were 2.9 and 1.7 % off over 6 s (16: 0.5 %):
    the pairs of modes the clamp barely moves pushed psi_00 out.
    """
    model, basis = resonance
    sims = {count: ModalSimulation(model, basis, FilterBand('lowpass', 0, count - 1, 'index'),
                                   ModalSettings(dt=5e-4, basis_kind='derivatives'))
            for count in (16, 24, 32)}
    errors = errors_against_full(model, basis, sims, 6.0, 5e-4)
    assert all(overall < 0.003 for _, overall in errors.values()), errors


def test_drive_gains_weigh_the_modes_the_clamp_shakes():
    """About 1 / (2 h) at resonance, 1 well above the drive, bounded without damping."""
    model = MassSpringModel(load_scene('sheet_10x10_resonance'))
    omega = 2 * math.pi * np.array([4.7357, 20.0, 80.0])   # the drive is mode 0's frequency
    gain = drive_gains(model, omega)
    assert gain[0] == pytest.approx(1 / (2 * 0.02), rel=1e-6)
    assert gain[1] == pytest.approx(1 / (1 - (4.7357 / 20.0) ** 2), rel=0.01)
    assert gain[2] == pytest.approx(1.0, abs=0.01)
    undamped = MassSpringModel(variant('sheet_10x10_resonance', damping={'ratio': 0.0}))
    assert drive_gains(undamped, omega)[0] == MAX_DRIVE_GAIN
    still = MassSpringModel(load_scene('chain_2'))        # a clamp that does not move
    assert np.array_equal(drive_gains(still, omega), np.ones(3))


def test_a_band_pass_puts_nothing_back_into_the_modes_it_removes(resonance):
    model, basis = resonance
    sim = ModalSimulation(model, basis, FilterBand('bandpass', 2, 48, 'index'),
                          ModalSettings(dt=5e-4, basis_kind='derivatives'))
    removed = basis.vectors[:, :2]
    mass = model.mass_dof
    inside = total = 0.0
    for _ in range(int(6.0 / 5e-4)):
        sim.step()
        u = sim.displacement()
        q = removed.T @ (mass * u)
        inside += float(q @ q)
        total += float(u @ (mass * u))
    assert inside < 1e-9 * total


@pytest.mark.slow
def test_the_32x32_resonance_scene_stays_within_half_a_percent():
    """0.16 % over 6 s (1.2 % before the pairs were weighted by the drive's amplification)."""
    model = MassSpringModel(load_scene('sheet_32x32_resonance'))
    basis = ModalBasis(model)
    full_dt = 0.5 * 2.0 / basis.omega_max_estimate()     # the full run's half limit
    sim = ModalSimulation(model, basis, LOWPASS_0_14,
                          ModalSettings(dt=2 * full_dt, basis_kind='derivatives'))
    (_, overall), = errors_against_full(model, basis, {'d': sim}, 6.0, 2 * full_dt,
                                        full_dt).values()
    assert overall < 0.005


def test_a_large_scene_computes_the_same_coordinates_in_the_worker():
    model = MassSpringModel(load_scene('sheet_10x10_resonance'))
    dense = added_coordinates(ModalBasis(model), np.arange(15))
    with WorkerProcess('test_derivatives') as worker:
        sparse_basis = ModalBasis(model, dense_limit=0, worker=worker, initial_modes=32)
        sparse = added_coordinates(sparse_basis, np.arange(15))
    assert sparse.count == dense.count
    np.testing.assert_allclose(sparse.omega, dense.omega, rtol=1e-7)
    # the same subspace (each vector up to sign)
    overlap = np.abs(sparse.vectors.T @ (model.mass_dof[:, None] * dense.vectors))
    np.testing.assert_allclose(np.sort(overlap.max(axis=1)), 1.0, atol=1e-6)


def test_a_band_change_fades_the_added_coordinates_without_a_jump():
    model = MassSpringModel(load_scene('sheet_10x10'))
    basis = ModalBasis(model)
    sim = ModalSimulation(model, basis, FilterBand('lowpass', 0, 20, 'index'),
                          ModalSettings(dt=5e-4, basis_kind='derivatives'))
    sim.step(4000)                                         # 2 s: swaying steadily

    ordinary = max_step_motion(sim, 2000)
    first = set(sim.stepped_modes.tolist())
    for band in (FilterBand('lowpass', high=14, by='index'),
                 FilterBand('bandpass', 2, 30, by='index'), FilterBand('lowpass', 0, 20, 'index')):
        sim.set_band(band)
        assert sim.fading
        assert max_step_motion(sim, 2700) <= ordinary           # the fade and what follows it
    assert not sim.fading
    assert sim.kept_modes.tolist() == list(range(21))
    assert set(sim.stepped_modes.tolist()) == first        # the band's own coordinates again


def test_static_loads_outside_the_band_are_left_out():
    """
    sheet_10x10 sways at 0.7 Hz in x and shakes at 8 Hz in y.

    A low-pass below 8 Hz adds the static response to gravity and the sway, not to the shake (it
    would move at 8 Hz).
    """
    model = MassSpringModel(load_scene('sheet_10x10'))
    mass, d = model.mass_dof, model.dimension
    every = static_load_vectors(model)
    assert every.shape[1] == 3
    np.testing.assert_array_equal(every[:, 0], model.gravity_force)
    np.testing.assert_array_equal(every[0::d, 1], mass[0::d])       # x: M 1_x
    np.testing.assert_array_equal(every[1::d, 2], mass[1::d])       # y: M 1_y
    below_8 = static_load_vectors(model, 0.0, 7.0)
    np.testing.assert_array_equal(below_8, every[:, :2])
    above = static_load_vectors(model, 5.0, 100.0)                  # a band from 5 Hz up
    np.testing.assert_array_equal(above, every[:, 2:])


def test_a_low_pass_with_derivatives_does_not_pass_a_load_above_it():
    """
    sheet_10x10 shakes at 8 Hz in y.

    A low-pass below it (mode 0, 4.7 Hz) must not let the added coordinates carry that shake,
    although they overlap its load.
    """
    model = MassSpringModel(load_scene('sheet_10x10'))
    basis = ModalBasis(model)
    shake = {}
    for kind in ('rest', 'derivatives', 'every mode'):
        band = FilterBand() if kind == 'every mode' else FilterBand('lowpass', 0, 7.0)
        basis_kind = 'rest' if kind == 'rest' else 'derivatives'
        sim = ModalSimulation(model, basis, band, ModalSettings(dt=5e-4, basis_kind=basis_kind))
        sim.step(2000)
        steps = 8000                                   # 4 s: 0.25 Hz bins
        shake[kind] = power_above(sim, 7.5, steps, below_hz=8.5)
    assert shake['every mode'] > 0.5                   # the shake is really there
    assert shake['derivatives'] < 1e-5 * shake['every mode'], shake
    assert shake['rest'] < 1e-5 * shake['every mode'], shake


def test_refreshed_forces_work_on_the_derivative_basis():
    """
    modal.force_refresh.

    The springs every N steps, the static tangent in between, on the band's modes and the
    coordinates they add.
    """
    model = MassSpringModel(load_scene('sheet_10x10'))
    basis = ModalBasis(model)
    sims = {n: ModalSimulation(model, basis, LOWPASS_0_14,
                               ModalSettings(dt=5e-4, forces=ForceOptions('refreshed', n),
                                             basis_kind='derivatives'))
            for n in (1, 10)}
    assert sims[10].force_report().error is not None and sims[1].force_report().error is None
    errors = errors_against_full(model, basis, sims, 3.0, 5e-4)
    assert errors[1][1] < 0.003 and errors[10][1] < 0.005, errors
    assert sims[10].force_report().error < 0.01


def test_band_changes_faster_than_the_fade_keep_the_displacement_and_the_run_stable():
    """
    Bands changed every 20 ms with a 0.2 s fade.

    Two bands' added coordinates fade over each other and describe much the same motion (they are
    not mass-orthogonal to each other). A change keeps every coordinate's state as it was
    (projecting the state onto the new set mixed the overlapping ones into each other, moved the
    sheet at every change and, in a storm of changes, made the run diverge).
    """
    model = MassSpringModel(load_scene('sheet_10x10'))
    basis = ModalBasis(model)
    sim = ModalSimulation(model, basis, FilterBand(),
                          ModalSettings(dt=5e-4, basis_kind='derivatives', transition_s=0.2))
    bands = [FilterBand('lowpass', 0, 12, 'hz'), FilterBand('bandpass', 5, 40, 'hz'),
             FilterBand('lowpass', 0, 20, 'index')]
    sim.step(400)
    for k in range(60):
        before = sim.displacement()
        sim.set_band(bands[k % 3])
        np.testing.assert_allclose(sim.displacement(), before, rtol=0,
                                   atol=1e-12 * np.abs(before).max())
        sim.step(40)                                      # raises DivergenceError if unstable
    assert sim.max_strain() < 0.05


def test_runs_rebuilt_on_one_basis_compute_a_bands_derivatives_once():
    """A parameter change rebuilds the run (other forces, another step): same added coordinates."""
    model = MassSpringModel(load_scene('sheet_10x10_resonance'))
    said = []
    basis = ModalBasis(model, progress=said.append)
    band = FilterBand('lowpass', 0, 14, 'index')
    first = rebuild(model, basis, SimulationConfig(band=band, basis='derivatives'))
    again = rebuild(model, basis, SimulationConfig(band=band, basis='derivatives',
                                                   forces='refreshed', dt=2e-4))
    assert sum('modal derivatives' in line for line in said) == 1, said
    assert first._bank is again._bank


def test_bands_of_the_same_pair_modes_share_their_solves_and_get_the_same_coordinates(
        monkeypatch):
    """A plan and its richer sibling (more modes, more directions): one set of pair solves."""
    model = MassSpringModel(load_scene('sheet_10x10_resonance'))
    solved = []
    pair_solutions = derivatives.pair_solutions

    def counted(*args, **kwargs):
        solved.append(args[2].shape[1])
        return pair_solutions(*args, **kwargs)
    monkeypatch.setattr(derivatives, 'pair_solutions', counted)
    shared_basis, lines = ModalBasis(model), []
    keep = np.arange(MAX_PAIR_MODES + 6)
    plan = added_coordinates(shared_basis, keep[:MAX_PAIR_MODES + 2], 15, lines.append)
    sibling = added_coordinates(shared_basis, keep, 30, lines.append)
    assert solved == [MAX_PAIR_MODES] and len(shared_basis.pair_solves) == 1
    assert 'kept from another band' in lines[1] and 'kept' not in lines[0]
    # the same coordinates as solved afresh, to the last bit
    for band, directions, got in ((keep[:MAX_PAIR_MODES + 2], 15, plan), (keep, 30, sibling)):
        fresh = added_coordinates(ModalBasis(model), band, directions)
        assert got.count == fresh.count and got.derivative_count == fresh.derivative_count
        np.testing.assert_array_equal(got.vectors, fresh.vectors)
        np.testing.assert_array_equal(got.omega, fresh.omega)
    assert solved == [MAX_PAIR_MODES] * 3
    # a basis whose pair modes changed (solved anew) solves them again
    shared_basis.vectors = shared_basis.vectors.copy()
    shared_basis.vectors[:, 0] *= -1.0
    added_coordinates(shared_basis, keep, 30)
    assert solved == [MAX_PAIR_MODES] * 4

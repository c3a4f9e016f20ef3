"""The filter band: validation, mode choice, spectral effect, smooth changes."""
from __future__ import annotations

import math

from helpers import max_step_motion, power_above
from modal_spring_ros.core.bases.basis import ModalBasis
from modal_spring_ros.core.filter_band import BandError, FilterBand
from modal_spring_ros.core.forces import ForceOptions
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.simulations import ModalSettings, ModalSimulation
import modal_spring_ros.core.simulations.stepped_set as stepped_set
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest

FREQS = np.array([1.0, 2.0, 5.0, 9.0, 20.0])


@pytest.mark.parametrize('band, kept', [
    (FilterBand(), [0, 1, 2, 3, 4]),
    (FilterBand('lowpass', high=5.0), [0, 1, 2]),
    (FilterBand('highpass', low=5.0), [2, 3, 4]),
    (FilterBand('bandpass', 2.0, 9.0), [1, 2, 3]),
    (FilterBand('bandstop', 2.0, 9.0), [0, 4]),
    (FilterBand('lowpass', high=1, by='index'), [0, 1]),
    (FilterBand('bandpass', 1, 3, by='index'), [1, 2, 3]),
    (FilterBand('bandstop', 1, 3, by='index'), [0, 4]),
])
def test_band_keeps_the_documented_modes(band, kept):
    assert np.flatnonzero(band.validate().keeps(FREQS)).tolist() == kept


@pytest.mark.parametrize('band, message', [
    (FilterBand('bandpass', 5.0, 2.0), 'low_hz (5) must be below high_hz (2) for bandpass'),
    (FilterBand('bandstop', 3.0, 3.0), 'low_hz (3) must be below high_hz (3)'),
    (FilterBand('lowpass', high=-1.0), 'high_hz (-1) must not be negative'),
    (FilterBand('highpass', low=math.nan), 'low_hz (nan) must be finite for highpass'),
    (FilterBand('lowpass', high=math.inf), 'high_hz (inf) must be finite for lowpass'),
    (FilterBand('notch'), "filter type 'notch' is not one of allpass, lowpass"),
    (FilterBand('lowpass', high=2.5, by='index'), 'high_mode (2.5) must be a whole'),
])
def test_impossible_bands_are_rejected_with_the_rule(band, message):
    with pytest.raises(BandError) as err:
        band.validate()
    assert str(err.value).startswith(message)


def test_a_front_end_s_names_are_the_ones_an_error_says():
    names = {'type': 'filter.type', 'low_hz': 'filter.low_hz', 'high_hz': 'filter.high_hz'}
    with pytest.raises(BandError, match=r'^filter.low_hz \(5\) must be below filter.high_hz'):
        FilterBand('bandpass', 5.0, 2.0).validate(names)
    with pytest.raises(BandError, match="^filter.type 'notch'"):
        FilterBand('notch').validate(names)


def test_fig_10_bands_keep_the_papers_mode_counts(sheet_10x10):
    model, basis = sheet_10x10
    low = ModalSimulation(model, basis, FilterBand('lowpass', 0, 14, 'index'),
                          ModalSettings(dt=5e-4))
    assert low.kept_modes.tolist() == list(range(15))           # 165 of 180 dropped
    band = ModalSimulation(model, basis, FilterBand('bandpass', 2, 48, 'index'),
                           ModalSettings(dt=5e-4))
    assert band.kept_modes.tolist() == list(range(2, 49))      # 2 low + 131 high dropped
    assert 180 - band.kept_modes.size - 2 == 131


def test_a_band_that_keeps_no_mode_is_rejected(sheet_10x10):
    model, basis = sheet_10x10
    with pytest.raises(BandError, match=r'keeps no mode \(the computed modes span 4.7'):
        ModalSimulation(model, basis, FilterBand('lowpass', high=1.0), ModalSettings(dt=5e-4))
    sim = ModalSimulation(model, basis, FilterBand(), ModalSettings(dt=5e-4))
    with pytest.raises(BandError):
        sim.set_band(FilterBand('bandpass', 5.0, 6.0))
    assert sim.band == FilterBand() and sim.kept_modes.size == 180  # nothing changed


def test_lowpass_leaves_under_one_percent_of_power_above_the_cutoff(sheet_undamped_still):
    model, basis = sheet_undamped_still
    # Broadband excitation: every mode displaced by the same modal amplitude (white).
    u0 = basis.vectors @ np.random.default_rng(1).normal(scale=2e-4, size=basis.count)
    cutoff = 20.0
    low = ModalSimulation(model, basis, FilterBand('lowpass', high=cutoff), ModalSettings(dt=5e-4))
    low.set_state(u0, np.zeros(model.n_free_dof))
    every = ModalSimulation(model, basis, FilterBand(), ModalSettings(dt=5e-4))
    every.set_state(u0, np.zeros(model.n_free_dof))
    assert power_above(low, cutoff, 6000) < 0.01
    assert power_above(every, cutoff, 6000) > 0.2     # the excitation really is broadband


def test_changing_the_band_mid_run_moves_no_particle_more_than_ordinary_motion(sheet_10x10):
    model, basis = sheet_10x10
    sim = ModalSimulation(model, basis, FilterBand(),
                          ModalSettings(dt=5e-4))   # default 0.5 s transition
    sim.step(4000)                                        # 2 s: swaying steadily

    ordinary = max_step_motion(sim, 2000)
    for band in (FilterBand('lowpass', high=14, by='index'), FilterBand('highpass', low=10.0),
                 FilterBand('bandpass', 2, 48, by='index'), FilterBand()):
        sim.set_band(band)
        assert max_step_motion(sim, 2700) <= ordinary         # the fade and what follows it
    assert not sim.fading and sim.stepped_modes.size == 180


def test_a_leaving_mode_fades_out_and_is_then_dropped(sheet_10x10):
    model, basis = sheet_10x10
    sim = ModalSimulation(model, basis, FilterBand(), ModalSettings(dt=5e-4, transition_s=0.1))
    sim.step(1000)
    q_before = sim.modal_coordinates[0]
    sim.set_band(FilterBand('highpass', low=6.0))      # drops mode 0 (4.7 Hz)
    assert sim.fading and 0 in sim.stepped_modes and 0 not in sim.kept_modes
    assert sim.modal_coordinates[0] == pytest.approx(q_before)   # no jump at the change
    sim.step(100)                                        # half the transition
    assert sim.fading and abs(sim.modal_coordinates[0]) < abs(q_before)
    sim.step(100)
    assert not sim.fading and 0 not in sim.stepped_modes


def test_an_entering_mode_starts_from_rest(sheet_10x10):
    model, basis = sheet_10x10
    sim = ModalSimulation(model, basis, FilterBand('highpass', low=6.0), ModalSettings(dt=5e-4))
    sim.step(1000)
    sim.set_band(FilterBand())
    k = int(np.flatnonzero(sim.stepped_modes == 0)[0])
    assert sim.modal_coordinates[k] == 0.0


def test_modes_not_computed_yet_are_computed_when_a_band_needs_them():
    model = MassSpringModel(load_scene('sheet_32x32'))
    basis = ModalBasis(model, initial_modes=16)
    sim = ModalSimulation(model, basis, FilterBand('lowpass', high=15, by='index'),
                          ModalSettings(dt=5e-4))
    sim.step(400)
    before = sim.positions()
    high = float(basis.frequencies_hz[-1]) * 2.0
    sim.set_band(FilterBand('lowpass', high=high))
    assert basis.count > 16 and basis.frequencies_hz[-1] > high
    assert sim.kept_modes.size == int(np.sum(basis.frequencies_hz <= high))
    np.testing.assert_allclose(sim.positions(), before, atol=1e-12)  # state carried over
    sim.step(100)
    assert np.isfinite(sim.positions()).all()


def test_automatic_mode_choice_meets_its_tolerance_with_few_modes():
    """
    modal.auto.

    The fewest modes whose predicted (static) truncation error is within the tolerance; the
    prediction is exact for the static response and matches a full run.
    """
    from modal_spring_ros.core.bases.mode_selection import choose_modes, TruncationEstimator
    from modal_spring_ros.core.config import SimulationConfig
    from modal_spring_ros.core.factory import build_simulation
    from modal_spring_ros.core.simulations import FullSimulation
    model = MassSpringModel(load_scene('sheet_10x10'))
    basis = ModalBasis(model)
    choice = choose_modes(model, basis, tolerance=0.01)
    assert choice.predicted_error <= 0.01 and 5 < choice.count < 40
    fewer = TruncationEstimator(model).errors(basis, choice.modes[:-1])
    assert max(fewer.values()) > 0.01 or choice.highest_hz < 2 * 8.0  # none fewer would do
    # exactness of the prediction: static response of the kept modes against K^-1 f
    import scipy.sparse.linalg as spla
    f = model.gravity_force
    u = spla.spsolve(model.stiffness_free.tocsc(), f)
    phi = basis.vectors[:, choice.modes]
    u_r = phi @ ((phi.T @ f) / basis.omega[choice.modes] ** 2)
    m = model.mass_dof
    actual = np.sqrt((u - u_r) @ (m * (u - u_r)) / (u @ (m * u)))
    assert actual == pytest.approx(choice.load_errors['gravity'], rel=1e-6)
    # the automatic run: its dt follows from the kept modes, and it tracks the full run
    sim = build_simulation(load_scene('sheet_10x10'), SimulationConfig(auto=True, tolerance=0.01))
    assert sim.kept_modes.size == choice.count and sim.dt < 0.9 * 2 / choice.omega_max + 1e-12
    sub = int(np.ceil(sim.dt / 4e-4))                   # the reference steps dt / sub
    full = FullSimulation(model, dt=sim.dt / sub, basis=basis)
    steps = int(round(1.0 / sim.dt))
    sim.step(steps)
    full.step(steps * sub)
    assert full.time == pytest.approx(sim.time, abs=1e-9)
    err = np.linalg.norm(sim.displacement() - full.displacement()) / np.linalg.norm(
        full.displacement())
    assert err < 0.05


def test_a_switch_prepared_ahead_builds_nothing_when_applied_and_changes_no_result(
        sheet_10x10, monkeypatch):
    """
    The node prepares a band switch in its parameter thread.

    Applying it in the stepping thread must then only map the state, and the run must be the same
    as unprepared.
    """
    model, basis = sheet_10x10
    band = FilterBand('bandpass', 10, 40, by='index')   # from 0..30: steps 0..40, then 10..40
    runs = []
    for prepare in (False, True):
        sim = ModalSimulation(model, basis, FilterBand('bandpass', 0, 30, by='index'),
                              ModalSettings(dt=5e-4, transition_s=0.05,
                                            forces=ForceOptions('refreshed', 5)))
        sim.step(300)
        if prepare:
            sim.prepare_switch(band)
            built = []
            real = stepped_set.ExactForces
            monkeypatch.setattr(stepped_set, 'ExactForces',
                                lambda *a: built.append(a) or real(*a))
        sim.set_band(band)
        assert sim.fading and sim.stepped_modes.tolist() == list(range(41))
        sim.step(200)                                    # through the end of the fade
        assert not sim.fading and sim.stepped_modes.tolist() == list(range(10, 41))
        if prepare:
            assert built == []                             # both sets were built ahead
            monkeypatch.undo()
        runs.append(sim.positions())
    np.testing.assert_array_equal(runs[1], runs[0])

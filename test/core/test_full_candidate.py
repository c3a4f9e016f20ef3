"""The full run as auto's candidate, measured by its own step doubling where nothing else can."""
from __future__ import annotations

import dataclasses
import math

from modal_spring_ros.core.auto import measured_error
from modal_spring_ros.core.auto.full_candidate import (against_reference, at_predicted_step,
                                                       by_step_doubling, halvings_work)
from modal_spring_ros.core.auto.measured_error import (converged_trajectory, horizon_error,
                                                       on_samples, trajectory, trajectory_error)
from modal_spring_ros.core.auto.plan import PilotReport
from modal_spring_ros.core.auto.sibling_check import DOUBLING_WORK, full_run_start, MIN_SHARE
from modal_spring_ros.core.auto.step_error import predicted_step, StepPrediction
from modal_spring_ros.core.auto.work_model import work_per_second
from modal_spring_ros.core.bases.basis import ModalBasis
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.scenes.resources import load_scene
import pytest

SAMPLE_S, SAMPLES = 0.02, 100


@pytest.fixture(scope='module')
def sheet():
    """Return the full run builder of ``sheet_10x10`` and its converged trajectory."""
    base = build_simulation(load_scene('sheet_10x10'), SimulationConfig(method='full'))

    def full(longest_dt: float, sample_s: float):
        return on_samples(base, sample_s, min(0.9 * base.stability_limit(), longest_dt))

    reference, _ = converged_trajectory(lambda dt: full(dt, SAMPLE_S),
                                        0.05 * base.stability_limit(), SAMPLE_S, SAMPLES, 1e-5)
    return full, reference


@pytest.mark.parametrize('budget', [1e-2, 1e-3])
def test_step_doubling_finds_the_longest_step_within_budget_and_its_true_error(sheet, budget):
    full, reference = sheet
    sim, estimate = by_step_doubling(full, SAMPLE_S, SAMPLES, SAMPLE_S * SAMPLES, budget,
                                     math.inf)
    achieved = trajectory_error(trajectory(sim, SAMPLE_S, SAMPLES), reference)
    assert estimate <= budget
    assert achieved == pytest.approx(estimate, rel=0.05)            # Richardson: four thirds
    longer = full(2.0 * sim.dt, SAMPLE_S)
    if longer.dt > sim.dt * 1.5:                                     # not at the stable limit
        assert trajectory_error(trajectory(longer, SAMPLE_S, SAMPLES), reference) > budget


def test_out_of_work_it_returns_the_coarser_run_with_its_estimate(sheet):
    full, reference = sheet
    sim, estimate = by_step_doubling(full, SAMPLE_S, SAMPLES, SAMPLE_S * SAMPLES, 1e-9, 0.0)
    assert sim.dt == pytest.approx(full(math.inf, SAMPLE_S).dt)      # one pair, no more
    assert estimate > 1e-9
    achieved = trajectory_error(trajectory(sim, SAMPLE_S, SAMPLES), reference)
    assert achieved == pytest.approx(estimate, rel=0.05)


def test_a_halving_beyond_its_work_is_not_run(sheet, monkeypatch):
    """
    The first pair always runs; a finer run only where the work stays within its bound.

    And only where the halvings the budget needs stay within it: each halving shrinks a
    second-order error four times (counted as eight), for a run of twice the work.
    """
    full, _ = sheet
    calls = []

    def counted(*args, **kwargs):
        calls.append(args[0].dt)
        return trajectory(*args, **kwargs)
    monkeypatch.setattr(measured_error, 'trajectory', counted)
    first = full(math.inf, SAMPLE_S)
    sim, paired = by_step_doubling(full, SAMPLE_S, SAMPLES, SAMPLE_S * SAMPLES, 1e-12, 0.0)
    assert len(calls) == 2 and sim.dt == pytest.approx(first.dt)     # the pair: no bound
    assert halvings_work(paired, paired / 3.5) == 2.0                 # one halving
    assert halvings_work(paired, paired / 20.0) == 6.0                # two: 2 + 4
    assert halvings_work(paired, paired / 100.0) == 14.0              # three: 2 + 4 + 8
    assert halvings_work(math.inf, 1e-3) == 0.0 and halvings_work(1.0, 0.0) == math.inf
    pair = work_per_second(first) + work_per_second(full(first.dt / 2.0, SAMPLE_S))
    # the pair and one halving afforded, not the next (its run would pass the bound)
    within = pair + work_per_second(full(first.dt / 4.0, SAMPLE_S)) * 1.5
    calls.clear()
    sim, estimate = by_step_doubling(full, SAMPLE_S, SAMPLES, SAMPLE_S * SAMPLES,
                                     paired / 3.5, within)
    assert calls == pytest.approx([first.dt, first.dt / 2.0, first.dt / 4.0], rel=1e-6)
    assert sim.dt == pytest.approx(first.dt / 2.0) and estimate <= paired / 3.5
    # a budget two halvings away: they would pass the bound, so not even the first is run;
    # the pair's coarser run, with its estimate (beyond the budget: it says so)
    calls.clear()
    sim, estimate = by_step_doubling(full, SAMPLE_S, SAMPLES, SAMPLE_S * SAMPLES,
                                     paired / 20.0, within)
    assert calls == pytest.approx([first.dt, first.dt / 2.0], rel=1e-6)
    assert sim.dt == pytest.approx(first.dt) and estimate == paired


def test_a_second_look_at_the_same_start_steps_only_what_it_has_not(sheet, monkeypatch):
    """The runs' samples kept between looks: the start's pair once, then only finer runs."""
    full, _ = sheet
    stepped: dict = {}
    first = by_step_doubling(full, SAMPLE_S, SAMPLES, SAMPLE_S * SAMPLES, math.inf, 0.0,
                             stepped=stepped)
    assert len(stepped) == 2                                       # the step and its half
    calls = []

    def counted(*args, **kwargs):
        calls.append(args[0].dt)
        return trajectory(*args, **kwargs)
    monkeypatch.setattr(measured_error, 'trajectory', counted)
    again = by_step_doubling(full, SAMPLE_S, SAMPLES, SAMPLE_S * SAMPLES, math.inf, 0.0,
                             stepped=stepped)
    assert calls == [] and again[1] == first[1] and again[0].dt == first[0].dt
    finer = by_step_doubling(full, SAMPLE_S, SAMPLES, SAMPLE_S * SAMPLES, first[1] / 10.0,
                             math.inf, stepped=stepped)
    assert finer[1] <= first[1] / 10.0
    assert len(calls) >= 1 and min(calls) == pytest.approx(finer[0].dt / 2.0)
    assert all(dt < first[0].dt / 1.5 for dt in calls)            # the pair not stepped again


def test_a_full_run_beyond_the_tolerance_says_so():
    report = PilotReport(0.05, 0.2, 3.0, 'its own run at half the step', (), 'full', 1.0,
                         reason='no plan within 1.00% after refining: the best measured 16%',
                         tolerance=0.01)
    assert 'NOT within 1.00%' in report.describe()
    assert 'against its own run at half the step' in report.describe()
    within = PilotReport(0.004, 0.2, 3.0, 'the full run', (), 'full', 1.0, reason='r',
                         tolerance=0.01)
    assert 'NOT within' not in within.describe()


def test_a_full_run_chosen_over_a_plan_says_how_its_own_check_found_its_error():
    """
    Where the pilot's budget is spent, the full run's error is its own check's: said as found.

    A predicted error (checked over the start) is never printed as measured and extrapolated.
    """
    plan = PilotReport(0.02, 0.03, 1.0, 'the full run', (), 'modal', 0.1, tolerance=0.01,
                       horizon_s=6.0, window_error=0.015)
    checked = PilotReport(0.004, math.nan, 0.17, 'its own run at half the step', (), 'full',
                          1.0, horizon_s=6.0, window_error=0.0009, tolerance=0.01,
                          predicted=True)
    chosen = dataclasses.replace(plan, error=checked.error, method='full', cost_ratio=1.0,
                                 reason='no plan within 1.00% after refining',
                                 against=checked.against)
    assert 'drift extrapolated' in chosen.describe()          # as the plan's window had it
    told = chosen.as_checked(checked).describe()
    assert 'error 0.40% predicted over a 6 s run' in told, told
    assert '0.09% against its own run at half the step over the first 0.17 s' in told
    assert 'drift extrapolated' not in told
    assert chosen.as_checked(None) is chosen


def test_the_full_run_over_the_window_start_is_as_long_as_its_work_affords(sheet):
    full, reference = sheet
    one_window = work_per_second(full(math.inf, SAMPLE_S)) * SAMPLE_S * SAMPLES
    accuracy = 1e-3                 # a tenth of 1 %, as the pilot asks: two halvings here
    half = full_run_start(full, SAMPLE_S, SAMPLES, accuracy, DOUBLING_WORK * one_window / 2)
    assert half is not None and len(half) == SAMPLES // 2
    assert trajectory_error(half, reference[:len(half)]) <= accuracy     # converged
    assert full_run_start(full, SAMPLE_S, SAMPLES, accuracy,
                          DOUBLING_WORK * one_window * 0.9 * MIN_SHARE) is None  # too short


class _Disproved(StepPrediction):
    """A prediction every window disproves."""

    def confirmed(self, measured: float, dt: float, over_s: float, allowed: float) -> float:
        return math.nan


def test_the_full_candidate_is_never_shortened_below_the_step_its_modes_predict(sheet):
    """
    sheet_10x10 over 200 s at 1 %: its window's error, extrapolated as a drift, is no judge.

    Against the converged run over its first 2 s, extrapolated over 200 s, the step is shortened
    to 0.8 times the one every mode, stepped over the whole run with the step's period error,
    predicts within the margin (the full run priced 1.25 times what it costs there). The window
    confirms the prediction: that step is the candidate, its error the one predicted over the
    run, also where the reference's own step is longer. A window that disproves it shortens the
    step on, measured as without a prediction.
    """
    full, reference = sheet
    horizon, allowed = 200.0, 0.008
    scene = load_scene('sheet_10x10')
    model = MassSpringModel(scene)
    default = full(math.inf, SAMPLE_S)
    prediction = predicted_step(model, ModalBasis(model), 'explicit', 0.5 * default.dt, horizon,
                                allowed, default.dt)
    measured: dict = {}

    def error_of(sim):
        run = trajectory(sim, SAMPLE_S, SAMPLES)
        measured[sim.dt] = trajectory_error(run, reference)
        return horizon_error(run, reference, SAMPLE_S, horizon)

    def window_of(sim):
        return measured[sim.dt]
    drift, drift_error = against_reference(full, error_of, SAMPLE_S, allowed, 0.0)
    assert drift_error <= allowed and drift.dt < 0.9 * prediction.step        # shortened
    sim, error, window = at_predicted_step(full, error_of, window_of, SAMPLE_S, allowed, 0.0,
                                           prediction, SAMPLE_S * SAMPLES)
    assert 0.97 * prediction.step <= sim.dt <= prediction.step
    assert horizon_error(trajectory(sim, SAMPLE_S, SAMPLES), reference, SAMPLE_S,
                         horizon) > allowed                       # the drift would not have it
    assert error == pytest.approx(prediction.error_at(sim.dt)) and error <= allowed
    assert window == measured[sim.dt] <= allowed
    # a reference coarser than that step (converged over the window, not over the run): the
    # candidate still goes down to it
    sim, error, window = at_predicted_step(full, error_of, window_of, SAMPLE_S, allowed,
                                           1.2 * prediction.step, prediction, SAMPLE_S * SAMPLES)
    assert 0.97 * prediction.step <= sim.dt <= prediction.step and error <= allowed
    assert window == measured[sim.dt]
    # a window that disproves it: shortened on below it, measured as without a prediction
    disproved = _Disproved(prediction.step, prediction.error, prediction.predictor)
    sim, error, window = at_predicted_step(full, error_of, window_of, SAMPLE_S, allowed, 0.0,
                                           disproved, SAMPLE_S * SAMPLES)
    assert sim.dt < 0.97 * prediction.step and math.isnan(window)
    assert error == error_of(sim) <= allowed                      # measured, extrapolated
    # none: as against the reference alone
    sim, error, window = at_predicted_step(full, error_of, window_of, SAMPLE_S, allowed, 0.0,
                                           None, SAMPLE_S * SAMPLES)
    assert (sim.dt, error) == (drift.dt, drift_error) and math.isnan(window)

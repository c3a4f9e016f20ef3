"""
How a run's error is measured: one grid of instants, and the drift model beyond the window.

Analytic trajectories (two oscillations with and without a frequency error) check the drift
model against the error it extrapolates to; a chain's run checks the sample grid.
"""
from __future__ import annotations

import math

from modal_spring_ros.core.auto import measured_error
from modal_spring_ros.core.auto import pilot
from modal_spring_ros.core.auto.measured_error import (bounded_trajectory,
                                                       converged_trajectory, error_at_least,
                                                       horizon_error, on_samples, trajectory,
                                                       trajectory_error, worst_window)
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.scenes.generator import random_scene
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest


def _phase_drift(sample_s: float, samples: int, drift: float) -> tuple[np.ndarray, np.ndarray]:
    t = (np.arange(samples) + 1)[:, None] * sample_s
    omega = 2 * np.pi * np.array([1.3, 3.1])
    reference = np.sin(omega * t) + 0.01
    return np.sin(omega * (1 + drift) * t) + 0.01 + 1e-3, reference


def test_drift_beyond_the_window_is_extrapolated_from_the_window():
    """
    A frequency error: the drift model over the pilot's window predicts the error 10x later.

    The window spans eight periods of the slower oscillation, as the pilot's does; a shorter
    one (2.6 periods) over-predicts, never under-predicts.
    """
    sample_s = 0.01
    run, reference = _phase_drift(sample_s, 6000, 3e-4)
    over_60s = trajectory_error(run, reference)
    for window, within in ((600, 0.1), (200, 0.7)):
        measured = trajectory_error(run[:window], reference[:window])
        assert measured < over_60s / 8
        predicted = horizon_error(run[:window], reference[:window], sample_s, 60.0)
        assert over_60s <= predicted <= (1 + within) * over_60s, (window, predicted, over_60s)
        assert horizon_error(run[:window], reference[:window], sample_s,
                             window * sample_s) == measured           # within: measured


def test_an_error_that_does_not_grow_is_not_extrapolated():
    sample_s = 0.01
    run, reference = _phase_drift(sample_s, 300, 0.0)
    measured = trajectory_error(run, reference)
    assert horizon_error(run, reference, sample_s, 60.0) == pytest.approx(measured, rel=0.05)
    assert horizon_error(None, reference, sample_s, 60.0) == math.inf


def test_runs_are_compared_on_one_grid_of_instants():
    sim = build_simulation(load_scene('chain_2'), SimulationConfig(method='full', dt=0.003))
    with pytest.raises(ValueError, match='do not fall on steps'):
        trajectory(sim, 0.01, 5)
    landed = on_samples(sim, 0.01)
    assert landed.dt == pytest.approx(0.0025) and on_samples(landed, 0.01) is landed
    assert on_samples(sim, 0.01, longest_dt=0.004).dt == pytest.approx(0.01 / 3)
    assert trajectory(landed, 0.01, 5).shape == (5, sim.model.n_free_dof)


def test_the_error_of_a_run_part_way_bounds_its_error_over_the_window_from_below():
    """Whatever the rest of a run does, its error over the window is at least the bound."""
    rng = np.random.default_rng(0)
    reference = rng.normal(size=(200, 6))
    growing = np.linspace(0, 3, 200)[:, None]
    run = reference + rng.normal(scale=0.05, size=reference.shape) * growing
    whole = trajectory_error(run, reference)
    bounds = [error_at_least(run[:k], reference) for k in range(1, 201)]
    assert np.all(np.diff(bounds) >= 0) and bounds[-1] == pytest.approx(whole)
    assert bounds[99] < 0.5 * whole          # the error grows: the first half says little
    # the rest of the run exactly on the reference: the bound is what the window measures
    perfect = np.concatenate([run[:100], reference[100:]])
    assert trajectory_error(perfect, reference) == pytest.approx(bounds[99])


def test_a_run_certain_to_miss_is_abandoned_part_way_and_says_by_how_much_at_least():
    """
    sheet_10x10 on its modes below 8 Hz, against the full run: about 37 % off over 2 s.

    With a ceiling of 1 % its run stops after an eighth of the window, the bound it returns
    beyond 1 % and below the error of the whole window; without one it runs to the end.
    """
    scene = load_scene('sheet_10x10')
    sample_s, samples = 0.01, 200
    full = build_simulation(scene, SimulationConfig(method='full'))
    reference = trajectory(on_samples(full, sample_s, 1e-4), sample_s, samples)
    low_modes = on_samples(build_simulation(scene, SimulationConfig(
        method='modal', band=FilterBand(kind='lowpass', high=8.0))), sample_s)
    whole = trajectory_error(trajectory(low_modes, sample_s, samples), reference)
    assert whole > 0.3
    run, bound = bounded_trajectory(low_modes, sample_s, reference, ceiling=0.01)
    assert len(run) == samples // measured_error.GIVE_UP_CHECKS
    assert 0.01 < bound <= whole
    np.testing.assert_array_equal(run, trajectory(low_modes, sample_s, samples)[:len(run)])
    run, bound = bounded_trajectory(low_modes, sample_s, reference, ceiling=2 * whole)
    assert len(run) == samples and bound is None
    assert bounded_trajectory(low_modes, sample_s, reference)[1] is None


@pytest.mark.slow
def test_abandoning_trials_part_way_changes_no_plan_and_steps_less():
    """
    Random scene 11 at 0.3 %: a refinement trial is abandoned part-way, the plan is the same.

    The same pilot with every run taken to its window's end chooses the same plan, printing
    the same error, and steps more.
    """
    config = SimulationConfig(auto=True, tolerance=0.003, horizon_s=3.0, planning_share=None)
    whole_runs = bounded_trajectory
    plans, stepped, abandoned = [], [], []
    for give_up in (True, False):
        samples = []

        def measured(sim, sample_s, reference, ceiling=math.inf, kept=None):
            run, bound = whole_runs(sim, sample_s, reference, ceiling if give_up else math.inf,
                                    kept)
            samples.append(len(reference) if run is None else len(run))
            abandoned.extend([len(run) / len(reference)] if bound is not None else [])
            return run, bound
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(pilot, 'bounded_trajectory', measured)
            sim = build_simulation(random_scene(11, 80), config)
        plans.append((sim.method, sim.dt, sim.coordinates, sim.pilot.refined, sim.pilot.error))
        stepped.append(sum(samples))
    assert plans[0] == plans[1]
    assert len(abandoned) >= 1 and max(abandoned) < 1.0
    assert stepped[0] < stepped[1]


def test_samples_further_apart_than_a_window_are_each_a_window_of_their_own():
    """A prediction over a 1,000 s run samples every 0.5 s: each sample judged, none skipped."""
    reference = np.ones((2000, 3))
    run = reference.copy()
    run[1234] *= 1.3                      # one moment 30 % off
    assert worst_window(run, reference, 0.5) == pytest.approx(0.3)
    assert worst_window(run, reference, 0.5) >= trajectory_error(run, reference)
    assert worst_window(np.empty((0, 3)), np.empty((0, 3)), 0.5) == 0.0


def test_a_run_of_a_thousand_seconds_is_planned_with_its_step_predicted_over_it():
    """soft_block_3d over 1,000 s: its prediction samples every 0.5 s (it once stopped there)."""
    sim = build_simulation(load_scene('soft_block_3d'),
                           SimulationConfig(auto=True, tolerance=0.01, horizon_s=1000.0))
    report = sim.pilot
    assert report.predicted and report.error <= 0.01, report.describe()
    # the default step (half the stability limit) is predicted to miss over 1,000 s
    assert sim.dt < 0.5 * sim.stability_limit() and 'predicted beyond' in report.reason


def test_a_converged_run_asked_again_is_neither_stepped_nor_charged_again():
    """The pilot asks for its reference again after a refinement: its runs are kept."""
    full = build_simulation(load_scene('sheet_10x10'), SimulationConfig(method='full'))
    sample_s = full.dt * 20
    stepped, charged = {}, []

    def converged():
        return converged_trajectory(lambda dt: on_samples(full, sample_s, dt), full.dt,
                                    sample_s, 50, 1e-4, charge=charged.append, stepped=stepped)
    first = converged()
    runs = len(charged)
    again = converged()
    assert runs >= 2 and len(charged) == runs and len(stepped) == runs
    np.testing.assert_array_equal(first[0], again[0])

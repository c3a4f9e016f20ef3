"""
How a run's error is measured: one grid of instants, and the drift model beyond the window.

Analytic trajectories (two oscillations with and without a frequency error) check the drift
model against the error it extrapolates to; a chain's run checks the sample grid.
"""
from __future__ import annotations

import math

from modal_spring_ros.core.auto.measured_error import (horizon_error, on_samples, trajectory,
                                                       trajectory_error)
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
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

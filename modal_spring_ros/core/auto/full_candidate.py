"""
The full run as the automatic choice's candidate: the longest step it measures within budget.

Two ways to measure it, by what the pilot can trust:

- :func:`against_reference`: against the pilot's reference (the converged full run, or a
  richer modal plan that the plan itself measured within the tolerance against), from the
  longest stable step down; never below the step the modes predict within the tolerance where
  the window confirms that prediction (:func:`at_predicted_step`);
- :func:`by_step_doubling`: against itself at half the step. Where no modal plan came within
  the tolerance, the richer modal plan is no reference for anything (a scene the modal
  coordinates cannot follow, such as cloth whose slack regions turn nonlinear at millimetres),
  and measuring the full run against it reported the modal plan's error as the full run's and
  shortened its step for nothing. The full run's only error is its step error: a second-order
  scheme's error at ``h`` is four thirds of the difference between its runs at ``h`` and
  ``h / 2``.
"""
from __future__ import annotations

import math
from typing import Callable

from modal_spring_ros.core.auto.measured_error import horizon_error, stepped_trajectory
from modal_spring_ros.core.auto.step_error import StepPrediction
from modal_spring_ros.core.auto.work_model import work_per_second
from modal_spring_ros.core.simulations import RunState, Simulation
import numpy as np

#: Order of the schemes' step error.
STEP_ORDER = 2
#: What a full run measured by step doubling is said to be measured against.
BY_ITSELF = 'its own run at half the step'
#: A halving that leaves more than this share of the step doubling's estimate has not
#: converged (a second-order scheme's leaves a quarter, a first-order one's a half).
STALLED = 0.75
#: Halvings in a row that stall before a run is taken not to converge in its step.
STALLS = 2
#: The most a halving is counted to shrink a step error by, where the halvings a search still
#: needs are counted (:func:`halvings_work`): twice what the order gives.
BEST_SHRINK = 2.0 ** (STEP_ORDER + 1)


def against_reference(full: Callable[[float, float], Simulation],
                      error_of: Callable[[Simulation], float], sample_s: float, budget: float,
                      shortest: float, floor: float = 0.0, first: float = math.inf
                      ) -> tuple[Simulation, float]:
    """
    Return the full run at the longest step whose ``error_of`` is within ``budget``, and it.

    Steps from the longest stable one (``full(longest_dt, sample_s)`` caps it; or from
    ``first``), shortened to where the step error (of order ``STEP_ORDER``) would meet the
    budget, by a factor of 0.5 to 0.8 each time, down to ``shortest``, and never below
    ``floor`` (the run at ``floor`` returned where no longer step meets the budget, its error as
    measured: the step the modes predict within the tolerance, judged by the caller).
    """
    step = first
    while True:
        sim = full(step, sample_s)
        error = error_of(sim)
        if error <= budget or sim.dt <= max(shortest, floor * (1.0 + 1e-9)):
            return sim, error
        reach = 0.95 * (budget / error) ** (1.0 / STEP_ORDER) if error < math.inf else 0.0
        step = max(sim.dt * min(0.8, max(0.5, reach)), floor * (1.0 + 1e-9))


def at_predicted_step(full: Callable[[float, float], Simulation],
                      error_of: Callable[[Simulation], float],
                      window_of: Callable[[Simulation], float], sample_s: float, budget: float,
                      shortest: float, prediction: StepPrediction | None, window_s: float
                      ) -> tuple[Simulation, float, float]:
    """
    Return the full candidate against the reference, its error, and its window's (nan: none).

    :func:`against_reference` judges a step by its window's error extrapolated over the run as
    a drift (:func:`~.measured_error.horizon_error`), which on a damped scene over a long run
    shortens the step far below what it needs: ``soft_block_3d`` over 1,000 s at 1 % took
    0.11 ms where the modes predict 0.29 ms, its full run priced at 2.6 times what it costs
    there, and a plan costing 2.4 times that run was chosen over it. Where the modes predict
    the step within the tolerance (``prediction``: every mode stepped over the whole run with
    the step's period error and damping, :mod:`~.step_error`), the step is never shortened
    below it while that run's error over the window (``window_of``, over its ``window_s``)
    confirms the prediction (:meth:`~.step_error.StepPrediction.confirmed`): its error is then
    the one predicted over the run, as a full run taken without a plan is judged
    (:func:`~.unplanned_full.unplanned_full`): one error model for the full run, whether a
    plan was measured or not. Where the window disproves it, the step is shortened on as
    :func:`against_reference` shortens it.
    """
    prediction = prediction.sampled(sample_s) if prediction is not None else None
    floor = (prediction.step if prediction is not None and prediction.predictor
             and prediction.holds else 0.0)
    # down to the predicted step also where it is below the reference's (a window converged to
    # a tenth of the tolerance can drift beyond it over the run, as the prediction sees)
    sim, error = against_reference(full, error_of, sample_s, budget,
                                   min(shortest, floor) if floor else shortest, floor)
    if error <= budget or sim.dt > floor * (1.0 + 1e-9):
        return sim, error, math.nan
    window = window_of(sim)
    predicted = prediction.confirmed(window, sim.dt, window_s, budget)
    if predicted <= budget:     # (nan where the window disproves it)
        return sim, predicted, window
    return (*against_reference(full, error_of, sample_s, budget, shortest, first=sim.dt),
            math.nan)


def by_step_doubling(full: Callable[[float, float], Simulation], sample_s: float,
                     samples: int, horizon_s: float, budget: float, work_per_s: float,
                     first_dt: float = math.inf, stepped: dict | None = None
                     ) -> tuple[Simulation, float]:
    """
    Return the full run at the longest step its own step doubling puts within ``budget``.

    From the longest stable step (or ``first_dt``), halved while the estimate (four thirds of
    the difference to the run at half the step, over ``horizon_s`` as :func:`horizon_error`
    extrapolates it) is over the budget and the runs' modelled work (us per simulated second,
    summed) stays within ``work_per_s``: the first pair is always run, a finer run only where
    it keeps within it, and none where the halvings the budget needs would not
    (:func:`halvings_work`: a long run's step missing its tolerance 1,000 times over once
    halved at the cost of the run itself before it stopped). Where it never meets the budget,
    the finest pair's coarser run is returned with its estimate, which then says so. Where
    ``STALLS`` halvings in a row each leave more than ``STALLED`` of the estimate, the run does
    not converge in its step (a motion that amplifies its differences: halving costs twice as
    much and brings nothing): the first run is returned, its error infinite, as where a run
    diverges. ``stepped``: the runs kept between calls
    (:func:`~.measured_error.stepped_trajectory`), so that a second look at the same start
    steps nothing again (and a run can go on from where one ended: :func:`head_start`).
    """
    share = 1.0 / (1.0 - 0.5 ** STEP_ORDER)       # the coarse run's error / the difference
    stepped = {} if stepped is None else stepped
    stalls, before = 0, math.inf

    def run(sim: Simulation) -> np.ndarray | None:
        return stepped_trajectory(sim, sample_s, samples, stepped)

    first = coarse = full(first_dt, sample_s)
    coarse_run = run(coarse)
    spent = work_per_second(coarse)
    last = None     # the last pair's coarser run and its estimate
    while True:
        fine = full(coarse.dt / 2.0, sample_s)
        spent += work_per_second(fine)
        if last is not None and spent > work_per_s:
            return last
        fine_run = run(fine)
        if fine_run is None:
            return coarse, math.inf
        error = horizon_error(coarse_run, fine_run, sample_s, horizon_s) * share
        if error <= budget or spent > work_per_s:
            return coarse, error
        stalls = stalls + 1 if error > STALLED * before else 0
        if stalls >= STALLS:
            return first, math.inf
        last = (coarse, error)
        # the halvings the order says the budget needs, each run twice the last's work: where
        # even those cost more than is left, none is run
        if spent + work_per_second(fine) * halvings_work(error, budget) > work_per_s:
            return last
        coarse, coarse_run, before = fine, fine_run, error


def halvings_work(error: float, budget: float) -> float:
    """
    Return what the halvings that take ``error`` within ``budget`` cost, in the finer run's work.

    A step error of order ``STEP_ORDER`` shrinks four times a halving in its asymptotic range
    (less before it, on random scenes' searches); counted as ``BEST_SHRINK`` times, so that no
    search whose error falls faster is cut short: ``n`` halvings step finer runs of 2, 4, ...
    ``2 ** n`` times the last one's work. 0 where the error is not finite (a diverged run is
    halved to find a stable step, whatever the order says).
    """
    if not math.isfinite(error):
        return 0.0
    if not budget > 0.0:
        return math.inf
    needed = max(1, math.ceil(math.log(error / budget) / math.log(BEST_SHRINK) - 1e-9))
    return 2.0 ** (needed + 1) - 2.0


def head_start(stepped: dict, sim: Simulation) -> RunState | None:
    """
    Return the furthest state a run at ``sim``'s step reached in ``stepped``, or None.

    ``stepped``: :func:`by_step_doubling`'s runs, each from rest: a run of the same settings
    and step goes on from there as though it had stepped that far (the same steps).
    """
    ends = [run.end for (dt, _, _), run in stepped.items() if dt == sim.dt and run.end is not None]
    return max(ends, key=lambda state: state.time, default=None)

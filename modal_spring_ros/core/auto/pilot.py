"""
Measure, then trust: the automatic plan's error measured by a pilot run before it is used.

The automatic choice (:mod:`~modal_spring_ros.core.bases.mode_selection`,
:mod:`~modal_spring_ros.core.bases.basis_choice`) *predicts* the error of a plan (modes, basis,
forces, step). A prediction is a model of the error, and on a scene it was not tuned on it can
be wrong many times over. Adaptive ODE solvers never trust a step until a second estimate says
it is good; this module does the same for a whole plan:

1. **A pilot window** that excites what the scene excites (released under gravity from rest,
   its clamp drive) and lasts a few periods of the slowest kept mode and of the drive
   (1 to 3 s), or, for a drive near a kept mode, the time its response takes to build up
   (:mod:`~modal_spring_ros.core.auto.pilot_window`): a drift model fitted to a shorter
   window cannot see that build-up. Never longer than the run.
2. **A reference** for that window: the full physical run (every DOF, every spring, explicit,
   halved from its longest stable step until step doubling says it has converged) where the
   band keeps everything and its cost is within ``REFERENCE_WORK``; otherwise the richer
   sibling of the plan (an embedded pair: every spring on every step, the derivatives basis
   with twice the directions, more modes where the band allows, a quarter of the step). The
   sibling's step error is a sixteenth of the plan's (second-order schemes), so the difference
   is divided by ``1 - (h_sibling / h_plan)^2`` (Richardson): exact for the plan's step
   error, a few per cent high for the rest. A sibling still richer than a refined plan in
   every respect (modes, directions, forces, a step at most half its step: the factor is then
   4/3) is kept; otherwise a new one is made. A sibling shares what the modal coordinates
   cannot follow (a cloth's slack regions are nonlinear from millimetres: plan and sibling
   agreed to 0.06 % and were 100 % off the full run), so the full run is the reference
   wherever it can be afforded, and where it cannot over the whole window it is run over the
   window's start as far as the budget goes, and every run is measured against that too
   (:mod:`~modal_spring_ros.core.auto.sibling_check`).
3. **The measured error**: relative L2 of the free-DOF displacement in the clamp's frame over
   the window's samples, against the reference (as the benchmark measures it). The promise is
   over the run's *horizon* (its duration), which may be longer than the window: an undamped
   scene's phase error keeps growing after it. Beyond the window the error is extrapolated by
   a drift model (a constant plus a linear growth) fitted to the window's second half
   (:func:`horizon_error`).
4. **Refinement**: while the error is above ``PILOT_MARGIN`` of the tolerance, each refinement
   the plan still has (exact forces, the derivatives basis, more derivative directions, more
   modes, half the step) is tried alone and the one that measures lowest is kept (the cheaper
   one on a near tie), for at most ``MAX_ROUNDS`` rounds.
5. **The full run is a candidate**: where the band keeps every mode, the full run meets any
   tolerance, and its cost per simulated second is compared with the plan's by a work model
   fitted to measured step costs (deterministic: the same choice whatever the machine's load
   or thread count). The cheaper of the two that meets the tolerance is chosen; a plan that
   cannot be brought within the tolerance falls back to the full run, and says so
   (:mod:`~modal_spring_ros.core.auto.full_candidate` measures it).

Everything here is deterministic: no wall-clock time enters a decision.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Callable

from modal_spring_ros.core.auto.full_candidate import (against_reference, BY_ITSELF,
                                                       by_step_doubling, STEP_ORDER)
from modal_spring_ros.core.auto.measured_error import (converged_trajectory, horizon_error,
                                                       on_samples, trajectory, trajectory_error)
from modal_spring_ros.core.auto.pilot_window import pilot_window
from modal_spring_ros.core.auto.plan import PilotReport, PlanSettings
from modal_spring_ros.core.auto.run_watch import WatchReference
from modal_spring_ros.core.auto.sibling_check import full_run_start
from modal_spring_ros.core.auto.work_model import work_per_second
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.simulations import Simulation
import numpy as np

#: The measured error must be within this share of the tolerance (a margin for what the pilot
#: window does not see).
PILOT_MARGIN = 0.8
#: Most refinement rounds before the plan gives way to the full run.
MAX_ROUNDS = 5
#: Samples of the displacement over the window (at least).
SAMPLES = 120
#: The full reference run is used when its window costs at most this much modelled CPU time, us.
REFERENCE_WORK = 5e6
#: The reference's own error (by step doubling) must be within this share of the tolerance.
REFERENCE_ACCURACY = 0.1
#: The richer sibling's step is made this many times shorter than the plan's, and kept for a
#: refined plan while it is at least ``SIBLING_KEPT`` times shorter.
SIBLING_REFINEMENT, SIBLING_KEPT = 4.0, 2.0
#: Longest step a plan is lengthened to, as a share of its explicit stability limit (below
#: ``mode_selection.STABILITY_SAFETY``, beyond which a plan's step is cut to a safe one).
LONGEST_STEP = 0.85
#: Most derivative directions a refinement asks for.
MAX_PILOT_DIRECTIONS = 96
#: A candidate within this factor of another's measured error counts as a tie (cheaper wins).
TIE = 1.1
#: The full run replaces a plan within the tolerance where the work model prices the plan above
#: this many times the full run's work: auto never chooses a candidate it prices above 1.1 times
#: the cheapest it measured; within that the two are a tie (the model's ratios are good to about
#: 30 %), and the plan, which measured within the tolerance, is kept.
FULL_RUN_TIE = 1.1


class Pilot:
    """
    Refine a plan by measurement and choose between it and the full run.

    ``make(settings)`` builds the modal run of a plan; ``full(longest_dt, sample_s)`` the full
    run at a step no longer than ``longest_dt`` that lands on the samples (None when the band
    does not keep every mode: the full run is then neither reference nor candidate);
    ``more_modes(hz)`` the next mode limit above ``hz`` the band allows (None: none);
    ``can_halve_step``: the step is the plan's to choose (not given by the user);
    ``horizon_s``: how long the run is, s (the tolerance holds over it; None: the window).
    """

    def __init__(self, model: MassSpringModel, tolerance: float,
                 make: Callable[[PlanSettings], Simulation],
                 full: Callable[[float, float], Simulation] | None,
                 more_modes: Callable[[float], float | None], kept_hz: np.ndarray,
                 can_halve_step: bool = True, horizon_s: float | None = None):
        self.model = model
        self.can_halve_step = can_halve_step
        self.tolerance = float(tolerance)
        self.make = make
        self.full = full
        self.more_modes = more_modes
        window = pilot_window(model, kept_hz)
        self.horizon_s = float(horizon_s) if horizon_s is not None else window
        self.window_s = min(window, self.horizon_s)
        self._sibling: tuple[PlanSettings, float] | None = None   # the richer plan, its step
        # error over the window of each run measured against the current reference
        self._measured: dict[int, tuple[Simulation, float]] = {}
        self._sample_s = 0.0      # the sampling interval every run lands on (set by run)
        # what the full candidate is measured with: sample_s, samples, reference, against
        self._sampling: tuple[float, int, np.ndarray, str] | None = None
        # the full run over the window's start, checking a sibling reference (None: no check);
        # whether it was looked for
        self._start: np.ndarray | None = None
        self._start_sought = False
        self._fallback: Simulation | None = None   # the full candidate, once measured
        self._reference_dt = 0.0                   # the converged full reference's step

    def run(self, plan: PlanSettings) -> tuple[Simulation, PilotReport]:
        """Return the simulation chosen and what the pilot measured."""
        sim = self.make(plan)
        self._start, self._start_sought = None, False
        sample_s = sim.dt * max(1, int(round(self.window_s / SAMPLES / sim.dt)))
        self._sample_s = sample_s
        samples = max(1, int(math.ceil(self.window_s / sample_s)))
        reference, against = self._reference(plan, sim, sample_s, samples)
        budget = PILOT_MARGIN * self.tolerance
        error = planned = self._error(sim, reference, sample_s)
        refined: list[str] = []
        stale = False     # the plan was refined as far as its richer sibling in some respect
        for _ in range(2 * MAX_ROUNDS):
            if error <= budget and stale:
                reference, against, error = self._remeasured(plan, sim, sample_s, samples)
                stale = False
            if error <= budget or len(refined) >= MAX_ROUNDS:
                break
            options = []
            for name, candidate in self._refinements(plan):
                trial = self._build(candidate)
                measured = self._error(trial, reference, sample_s)
                options.append((measured, work_per_second(trial), name, candidate, trial))
            if not options:
                break
            best = min(o[0] for o in options)
            # the cheapest of those within a near tie of the best
            measured, _, name, plan, sim = min((o for o in options if o[0] <= TIE * best),
                                               key=lambda o: o[1])
            if measured >= error:
                break                                # nothing helps any more
            error = measured
            refined.append(name)
            stale = not self._still_poorer(plan, sim)
        if stale:
            reference, against, error = self._remeasured(plan, sim, sample_s, samples)
        if error <= budget and self.can_halve_step:
            plan, sim, error, longer = self._lengthened(plan, sim, error, reference, sample_s)
            refined.extend(['a longer step'] if longer else [])
        self._sampling = (sample_s, samples, reference, against)
        sim, report = self._choose(sim, error, planned, against, tuple(refined))
        window_error = report.error if report.method == 'full' else self._measured[id(sim)][1]
        return sim, dataclasses.replace(report, horizon_s=self.horizon_s,
                                        window_error=window_error, tolerance=self.tolerance)

    def watch_reference(self, sim: Simulation) -> WatchReference:
        """
        Return what the chosen modal ``sim`` is watched against while it runs.

        (:mod:`~modal_spring_ros.core.auto.run_watch`): the pilot's reference (the converged full
        run, or the richer plan with its Richardson share) on its samples; it falls back to the
        full candidate measured, or where the band keeps no full run to the richer plan (as
        settings: the whole band on its basis and forces, at a step within stability).
        """
        sample_s, samples, _, against = self._sampling
        richer, dt, full = (self._sibling or (None, 0.0))[0], self._reference_dt, self._fallback

        def reference() -> Simulation:
            return (self.full(dt * (1.0 + 1e-9), sample_s) if richer is None
                    else self._build(richer))
        if full is None:
            fallback, settings = reference, {
                'auto': False, 'basis': 'derivatives', 'forces': 'exact', 'force_refresh': 1,
                'derivative_directions': richer.directions, 'dt': None}
        else:
            fallback, settings = (lambda: full.with_dt(full.dt)), {
                'auto': False, 'method': 'full', 'integrator': full.integrator, 'dt': full.dt}
        work = work_per_second(sim)
        return WatchReference(reference, fallback, settings, against.split(' and ')[0],
                              sample_s, samples, self._shared(sim), self.tolerance, work,
                              work + work_per_second(reference()))

    # -- internals -----------------------------------------------------------------------------
    def _lengthened(self, plan: PlanSettings, sim: Simulation, error: float,
                    reference: np.ndarray, sample_s: float
                    ) -> tuple[PlanSettings, Simulation, float, bool]:
        """
        Return the plan at the longest step (up to ``LONGEST_STEP`` of its limit) within budget.

        A plan well within its budget pays for accuracy nobody asked for. Its step is
        lengthened (at most doubled) to where its step error (second order) would reach 90 % of
        the budget, and kept where the measured error is within it; twice at most. Whether any
        longer step was kept is returned last.
        """
        budget, longer = PILOT_MARGIN * self.tolerance, False
        for _ in range(2):
            reach = (0.9 * budget / error) ** (1.0 / STEP_ORDER) if error > 0.0 else 2.0
            step = min(min(2.0, reach) * sim.dt, LONGEST_STEP * sim.stability_limit())
            if step <= sim.dt * 1.1:
                return plan, sim, error, longer
            candidate = dataclasses.replace(plan, dt=step)
            trial = self._build(candidate)
            if trial.dt <= sim.dt * 1.05:
                return plan, sim, error, longer
            measured = self._error(trial, reference, sample_s)
            if measured > budget:
                return plan, sim, error, longer
            plan, sim, error, longer = candidate, trial, measured, True
        return plan, sim, error, longer

    def _build(self, settings: PlanSettings) -> Simulation:
        """
        Build the run of ``settings`` on the pilot's sample grid.

        A step cut to a stability limit lands anywhere; it is shortened to the next divisor of
        the sampling interval, so that every run is compared at the same instants (and the run
        measured is the run returned).
        """
        return on_samples(self.make(settings), self._sample_s)

    def _error(self, sim: Simulation, reference: np.ndarray, sample_s: float) -> float:
        """
        Return ``sim``'s error over the horizon.

        Measured over the window, extrapolated beyond it, and against a sibling corrected for
        the share of the step error the sibling shares.
        """
        run = trajectory(sim, sample_s, len(reference))
        shared = self._shared(sim)
        start = 0.0
        if self._sibling is not None and self._start is not None:
            start = trajectory_error(None if run is None else run[:len(self._start)],
                                     self._start)
        self._measured[id(sim)] = (sim, max(trajectory_error(run, reference) * shared, start))
        return max(horizon_error(run, reference, sample_s, self.horizon_s) * shared, start)

    def _shared(self, sim: Simulation) -> float:
        """Return the Richardson factor for ``sim`` against the sibling (1: the full run)."""
        if self._sibling is None:
            return 1.0
        ratio = self._sibling[1] / sim.dt
        finer = ratio <= (1.0 + 1e-6) / SIBLING_KEPT
        return 1.0 / (1.0 - ratio ** STEP_ORDER) if finer else 1.0

    def _still_poorer(self, plan: PlanSettings, sim: Simulation) -> bool:
        """Return whether the sibling is still richer than the refined ``plan`` everywhere."""
        if self._sibling is None:
            return True
        richer, dt = self._sibling
        return (sim.dt * (1.0 + 1e-6) >= SIBLING_KEPT * dt
                and (plan.highest_hz < richer.highest_hz
                     or self.more_modes(plan.highest_hz) is None)
                and (plan.basis_kind == 'rest' or plan.directions < richer.directions
                     or plan.directions >= MAX_PILOT_DIRECTIONS))

    def _remeasured(self, plan: PlanSettings, sim: Simulation, sample_s: float, samples: int
                    ) -> tuple[np.ndarray, str, float]:
        """
        Measure a refined plan against a sibling richer than *it*.

        A sibling made for the first plan can be the refined plan itself, and would measure 0.
        """
        reference, against = self._reference(plan, sim, sample_s, samples)
        return reference, against, self._error(sim, reference, sample_s)

    def _reference(self, plan: PlanSettings, sim: Simulation, sample_s: float, samples: int
                   ) -> tuple[np.ndarray, str]:
        """
        Return the reference for ``plan`` (built as ``sim``): the full run, or a richer sibling.

        The sibling's step is ``SIBLING_REFINEMENT`` times shorter than the step ``sim`` was
        built with (a plan's step can be cut to its stability limit when built: refining the
        plan's own could give the same run).
        """
        self._sibling, self._measured = None, {}
        if self.full is not None:
            found = self._converged_full_run(sample_s, samples)
            if found is not None:
                return found, 'the full run'
        richer = dataclasses.replace(
            plan, forces='exact', refresh=1, basis_kind='derivatives',
            directions=min(MAX_PILOT_DIRECTIONS, 2 * plan.directions),
            highest_hz=self.more_modes(plan.highest_hz) or plan.highest_hz,
            dt=min(plan.dt, sim.dt) / SIBLING_REFINEMENT)
        sibling = self._build(richer)
        reference = trajectory(sibling, sample_s, samples)
        self._sibling = (richer, sibling.dt)
        if reference is None:
            raise ValueError('modal.auto cannot measure a plan for this scene: the full run is '
                             'beyond its pilot budget and the richer modal plan diverges; run '
                             'it with method full')
        if self.full is not None and not self._start_sought:
            self._start_sought = True
            self._start = full_run_start(self.full, sample_s, samples,
                                         REFERENCE_ACCURACY * self.tolerance, REFERENCE_WORK)
        if self._start is None:
            return reference, 'a richer plan'
        return reference, (f'a richer plan and the full run over its first '
                           f'{len(self._start) * sample_s:.2g} s')

    def _converged_full_run(self, sample_s: float, samples: int) -> np.ndarray | None:
        """Return the full run's converged trajectory, or None beyond ``REFERENCE_WORK``."""
        step = self.full(math.inf, sample_s).dt
        found = converged_trajectory(lambda dt: self.full(dt, sample_s), step, sample_s,
                                     samples, REFERENCE_ACCURACY * self.tolerance,
                                     REFERENCE_WORK / self.window_s)
        if found is None:
            return None
        reference, self._reference_dt = found
        return reference

    def _refinements(self, plan: PlanSettings):
        if plan.forces != 'exact':
            yield 'exact forces', dataclasses.replace(plan, forces='exact', refresh=1)
        if plan.basis_kind == 'rest':
            yield 'derivatives basis', dataclasses.replace(plan, basis_kind='derivatives')
        elif plan.directions < MAX_PILOT_DIRECTIONS:
            yield 'more directions', dataclasses.replace(
                plan, directions=min(MAX_PILOT_DIRECTIONS, 2 * plan.directions))
        more = self.more_modes(plan.highest_hz)
        if more is not None:
            yield 'more modes', dataclasses.replace(plan, highest_hz=more)
        if self.can_halve_step:
            yield 'half the step', dataclasses.replace(
                plan, dt=plan.dt / 2,
                refresh=plan.refresh * 2 if plan.forces == 'refreshed' else 1)

    def _choose(self, sim: Simulation, error: float, planned: float, against: str,
                refined: tuple[str, ...]) -> tuple[Simulation, PilotReport]:
        if self.full is None:
            return sim, PilotReport(error, planned, self.window_s, against, refined, 'modal',
                                    math.nan)
        full, full_error, full_against = self._full_candidate(against, error)
        self._fallback = full
        ratio = work_per_second(sim) / work_per_second(full)
        report = PilotReport(error, planned, self.window_s, against, refined, 'modal', ratio)
        if error <= self.tolerance and ratio <= FULL_RUN_TIE:
            return sim, report
        reason = (f'no plan within {self.tolerance:.2%} after refining: the best measured '
                  f'{error:.2%}'
                  if error > self.tolerance else f'cheaper: the plan needs {ratio:.2g} x its work')
        return full, dataclasses.replace(report, error=full_error, method='full', cost_ratio=1.0,
                                         reason=reason, against=full_against)

    def _full_candidate(self, against: str, error: float) -> tuple[Simulation, float, str]:
        """
        Return the full run as a candidate, its error, and what that was measured against.

        Against the pilot's reference (:func:`~.full_candidate.against_reference`), down to
        the reference's step; without a full reference, against the richer sibling as the plan
        is (pricing it at the sibling's step unmeasured made a full run that met the tolerance
        at five times the step look three times dearer than a plan it cost a sixth of), unless
        the plan never came within the tolerance: then the sibling is no reference, and the
        full run is measured by its own step doubling (:func:`~.full_candidate.by_step_doubling`).
        """
        sample_s, samples, reference, _ = self._sampling
        budget = PILOT_MARGIN * self.tolerance
        if against != 'the full run' and error > self.tolerance:
            full, full_error = by_step_doubling(self.full, sample_s, samples, self.horizon_s,
                                                budget, REFERENCE_WORK / self.window_s)
            return full, full_error, BY_ITSELF
        shortest = self._reference_dt if against == 'the full run' else self._sibling[1]
        return (*against_reference(self.full, lambda sim: self._error(sim, reference, sample_s),
                                   sample_s, budget, shortest), against)

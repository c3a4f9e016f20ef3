"""
Measure, then trust: the automatic plan's error measured by a pilot run before it is used.

The automatic choice (:mod:`~modal_spring_ros.core.bases.mode_selection`,
:mod:`~modal_spring_ros.core.bases.basis_choice`) *predicts* the error of a plan (modes, basis,
forces, step); on a scene it was not tuned on a prediction can be wrong many times over. As
adaptive ODE solvers trust no step until a second estimate says it is good, the plan is run:

1. **A pilot window** that excites what the scene excites (from rest under gravity, with its
   clamp drive): a few periods of the slowest kept mode and of the drive, or a resonance's
   build-up, never longer than the run (:mod:`~modal_spring_ros.core.auto.pilot_window`).
2. **A reference** for it: the full run converged in its step (step doubling) where the band
   keeps everything and the budget affords it; otherwise the plan's richer sibling
   (:mod:`~.refinement`), its share of the plan's step error taken out (Richardson), checked
   against the full run over the window's start as the budget affords (:mod:`~.sibling_check`;
   it shares what the modes cannot follow): never one alone where the full run is a candidate.
3. **The error**: relative L2 of the free-DOF displacement in the clamp's frame over the
   window's samples, extrapolated over the run by a drift model (:func:`horizon_error`).
4. **Refinement** while above ``PILOT_MARGIN`` of the tolerance: each refinement left tried
   alone (abandoned once certain to do worse than the plan), the lowest (cheapest on a near tie)
   kept, for at most ``MAX_ROUNDS`` rounds; a plan well within it has its step lengthened.
5. **The full run is a candidate** (:mod:`~modal_spring_ros.core.auto.full_candidate`), at
   the step the modes predict where its window confirms it: the cheaper of the two by a work
   model (no clock) that meets the tolerance is chosen; the full run goes on from where the
   pilot's run of it ended (a head start).
6. **A budget** (:mod:`~modal_spring_ros.core.auto.budget`): every run priced before it is run,
   at most a share of the full run; where the cheapest measurement does not fit or would cost
   more than the plan could save, the full run. No wall-clock time enters a decision.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Callable

from modal_spring_ros.core.auto.budget import (PlanningBudget, REFERENCE_RUNS, training_work,
                                               worth_measuring)
from modal_spring_ros.core.auto.full_candidate import (at_predicted_step, BY_ITSELF,
                                                       by_step_doubling, head_start)
from modal_spring_ros.core.auto.measured_error import (bounded_trajectory, converged_trajectory,
                                                       horizon_error, on_samples, trajectory,
                                                       trajectory_error)
from modal_spring_ros.core.auto.pilot_window import pilot_window
from modal_spring_ros.core.auto.plan import PilotReport, PlanSettings
from modal_spring_ros.core.auto.refinement import (lengthened, refinements, richer,
                                                   shared_step_error, still_richer)
from modal_spring_ros.core.auto.sibling_check import DOUBLING_WORK, full_run_start
from modal_spring_ros.core.auto.step_error import StepPrediction
from modal_spring_ros.core.auto.unplanned_full import unplanned_full
from modal_spring_ros.core.auto.watch.windows import WatchReference
from modal_spring_ros.core.auto.work_model import work_per_second
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.simulations import Simulation
import numpy as np

#: The measured error must be within this share of the tolerance (a margin for the unseen).
PILOT_MARGIN = 0.8
#: Most refinement rounds before the plan gives way to the full run.
MAX_ROUNDS = 5
#: Samples of the displacement over the window (at least).
SAMPLES = 120
#: The full reference run is used when its window costs at most this much modelled CPU time, us.
REFERENCE_WORK = 5e6
#: The reference's own error (by step doubling) must be within this share of the tolerance.
REFERENCE_ACCURACY = 0.1
#: A candidate within this factor of another's measured error counts as a tie (cheaper wins).
TIE = 1.1
#: Why the full run is taken where its start could not be afforded beside a richer plan.
ALONE = ('a richer plan alone is no reference (it shares what the modes cannot follow: a '
         "turned solid's plan was 0.54 % from it and 6.2 % from the full run), and the full "
         "run over the window's start was beyond the planning budget")
#: The full run replaces a plan within the tolerance the work model prices above this many times
#: the full run's work (within it a tie, the model's ratios good to about 30 %: the plan kept).
FULL_RUN_TIE = 1.1


class Pilot:
    """
    Refine a plan by measurement and choose between it and the full run.

    ``make(settings)`` builds the modal run of a plan; ``full(longest_dt, sample_s)`` the full
    run at a step no longer than ``longest_dt`` that lands on the samples (None when the band
    does not keep every mode: the full run is then neither reference nor candidate);
    ``more_modes(hz)`` the next mode limit above ``hz`` the band allows (None: none);
    ``can_halve_step``: the step is the plan's to choose (not given by the user);
    ``horizon_s``: how long the run is, s (the tolerance holds over it; None: the window);
    ``budget``: what measuring may spend (:mod:`~modal_spring_ros.core.auto.budget`; None:
    not budgeted); ``full_dt``: the full run's default step (the one ``method full`` takes),
    and the longest step it is predicted to meet the tolerance at (None: no prediction).
    """

    def __init__(self, model: MassSpringModel, tolerance: float,
                 make: Callable[[PlanSettings], Simulation],
                 full: Callable[[float, float], Simulation] | None,
                 more_modes: Callable[[float], float | None], kept_hz: np.ndarray,
                 can_halve_step: bool = True, horizon_s: float | None = None,
                 budget: PlanningBudget | None = None,
                 full_dt: tuple[float, StepPrediction | None] = (math.inf, None)):
        self.model, self.full_dt, self.tolerance = model, full_dt, float(tolerance)
        self.budget = budget if budget is not None else PlanningBudget()
        self.make, self.full, self.more_modes = make, full, more_modes
        self.can_halve_step, self._checked = can_halve_step, None   # the full run's own check
        window = pilot_window(model, kept_hz)
        self.horizon_s = float(horizon_s) if horizon_s is not None else window
        self.window_s = min(window, self.horizon_s)
        self._sibling: tuple[PlanSettings, float] | None = None   # the richer plan, its step
        # error over the window of each run measured against the current reference
        self._measured: dict[int, tuple[Simulation, float]] = {}
        self._sample_s = 0.0      # the sampling interval every run lands on (set by run)
        # what the full candidate is measured with: sample_s, samples, reference, against
        self._sampling: tuple[float, int, np.ndarray, str] | None = None
        # the full run over the window's start checking a sibling (None: none); whether sought
        self._start, self._start_sought = None, False
        self._fallback: Simulation | None = None   # the full candidate, once measured
        self._reference_dt, self._stepped = 0.0, {}   # reference's step; full runs kept

    def run(self, plan: PlanSettings) -> tuple[Simulation, PilotReport]:
        """Return the simulation chosen and what the pilot measured."""
        sim = self.make(plan)
        self._start, self._start_sought = None, False
        sample_s = sim.dt * max(1, int(round(self.window_s / SAMPLES / sim.dt)))
        self._sample_s = sample_s
        samples = max(1, int(math.ceil(self.window_s / sample_s)))
        if self.full is not None and self.budget.bounded:
            sibling = work_per_second(self._build(richer(plan, sim.dt, self.more_modes)))
            why = worth_measuring(self.budget, self.full(math.inf, sample_s), sim, sibling,
                                  self.window_s, self.horizon_s)
            if why:
                return self._unplanned(why)
        found = self._reference(plan, sim, sample_s, samples)
        if found is None:
            return self._unplanned('no reference for a plan within the planning budget')
        reference, against = found
        if self.full is not None and 'the full run' not in against:
            return self._unplanned(ALONE)
        budget = PILOT_MARGIN * self.tolerance
        error = planned = self._error(sim, reference, sample_s)
        refined: list[str] = []
        stale = False     # the plan was refined as far as its richer sibling in some respect
        for _ in range(2 * MAX_ROUNDS):
            if error <= budget and stale:
                reference, against, error = self._remeasured(plan, sim, sample_s, samples,
                                                             (reference, against, error))
                stale = False
            if error <= budget or len(refined) >= MAX_ROUNDS:
                break
            options = []
            for name, candidate in refinements(plan, self.more_modes, self.can_halve_step,
                                               self._reference_dt):
                # a sampled plan of other coordinates trains its own sample when it is built
                if candidate.forces == 'sampled' and name != 'half the step':
                    training = training_work(self.model)
                    if not self.budget.affords(training):
                        continue
                    self.budget.spend(training)
                trial = self._build(candidate)
                if not self._affords(trial):
                    continue                         # beyond what the budget has left
                # a trial certain to be worse than the plan is never chosen: abandoned early
                measured = self._error(trial, reference, sample_s, ceiling=error)
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
            stale = self._sibling is not None and not still_richer(
                *self._sibling, plan, sim.dt, self.more_modes)
        if stale:
            reference, against, error = self._remeasured(plan, sim, sample_s, samples,
                                                         (reference, against, error))
        if error <= budget and self.can_halve_step:
            def measured(trial: Simulation) -> float | None:
                return (self._error(trial, reference, sample_s, ceiling=budget)
                        if self._affords(trial) else None)
            plan, sim, error, longer = lengthened(plan, sim, error, budget, self._build,
                                                  measured)
            refined.extend(['a longer step'] if longer else [])
        self._sampling = (sample_s, samples, reference, against)
        sim, report = self._choose(sim, error, planned, against, tuple(refined))
        checked = report.method == 'full' and self._checked is not None   # as its check said
        window_error = (report.window_error if checked else report.error
                        if report.method == 'full' else self._measured[id(sim)][1])
        return sim, dataclasses.replace(
            report, horizon_s=report.horizon_s if checked else self.horizon_s,
            window_error=window_error, tolerance=self.tolerance, planning=self.budget.describe())

    def watch_reference(self, sim: Simulation) -> WatchReference:
        """
        Return what the chosen modal ``sim`` is watched against while it runs.

        (:mod:`~.watch.run_watch`): the pilot's reference (the converged full run, or the
        richer plan with its Richardson share) on its samples; it falls back to the full
        candidate measured, or where the band keeps no full run to the richer plan (as
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
                              2.0 * work + work_per_second(reference()))

    # -- internals -----------------------------------------------------------------------------
    def _unplanned(self, reason: str) -> tuple[Simulation, PilotReport]:
        """Return the full run, its step checked within what the budget has left."""
        full, report = unplanned_full(self.full, self.budget, self.full_dt[0], self.window_s,
                                      self.horizon_s, self.tolerance, PILOT_MARGIN, SAMPLES,
                                      reason, self.full_dt[1])
        self._fallback = full
        return full, dataclasses.replace(report, planning=self.budget.describe())

    def _affords(self, sim: Simulation) -> bool:
        """Tell whether the budget pays for ``sim`` over the window."""
        return self.budget.affords(work_per_second(sim) * self.window_s)

    def _build(self, settings: PlanSettings) -> Simulation:
        """Build ``settings``'s run, its step a divisor of the samples' (compared at them)."""
        return on_samples(self.make(settings), self._sample_s)

    def _error(self, sim: Simulation, reference: np.ndarray, sample_s: float,
               ceiling: float = math.inf, stepped: dict | None = None) -> float:
        """
        Return ``sim``'s error over the horizon.

        Measured over the window, extrapolated beyond it, and against a sibling corrected for
        the share of the step error the sibling shares. A run whose error is certain to exceed
        ``ceiling`` part-way through its window is abandoned there (its bound returned, what
        was stepped charged: :func:`~.measured_error.bounded_trajectory`; kept in ``stepped``,
        charged once).
        """
        shared, new = self._shared(sim), (sim.dt, sample_s, len(reference)) not in (stepped or {})
        run, bound = bounded_trajectory(sim, sample_s, reference, ceiling / shared, stepped)
        self.budget.charge(sim, new * (len(reference) if run is None else len(run)) * sample_s)
        if bound is not None:
            self._measured[id(sim)] = (sim, bound * shared)
            return bound * shared
        start = 0.0
        if self._sibling is not None and self._start is not None:
            start = trajectory_error(None if run is None else run[:len(self._start)],
                                     self._start)
        self._measured[id(sim)] = (sim, max(trajectory_error(run, reference) * shared, start))
        return max(horizon_error(run, reference, sample_s, self.horizon_s) * shared, start)

    def _shared(self, sim: Simulation) -> float:
        """Return the Richardson factor for ``sim`` against the sibling (1: the full run)."""
        return 1.0 if self._sibling is None else shared_step_error(self._sibling[1], sim.dt)

    def _remeasured(self, plan: PlanSettings, sim: Simulation, sample_s: float, samples: int,
                    last: tuple[np.ndarray, str, float]) -> tuple[np.ndarray, str, float]:
        """
        Measure a refined plan against a sibling richer than *it*.

        A sibling made for the first plan can be the refined plan itself, and would measure 0.
        Where the budget affords no new reference, the last one stands (and its measurement).
        """
        kept = self._sibling, self._measured
        found = self._reference(plan, sim, sample_s, samples)
        if found is None:
            self._sibling, self._measured = kept
            return last
        reference, against = found
        return reference, against, self._error(sim, reference, sample_s)

    def _reference(self, plan: PlanSettings, sim: Simulation, sample_s: float, samples: int
                   ) -> tuple[np.ndarray, str] | None:
        """
        Return the reference for ``plan`` (built as ``sim``): the full run, or a richer sibling.

        The sibling (:func:`~.refinement.richer`) steps a quarter of the step ``sim`` was built
        with (a plan's step can be cut to its stability limit when built: refining the plan's
        own could give the same run). Each is priced before it is run: the full run's
        step doubling at ``DOUBLING_WORK`` runs over the window, the sibling at its own work.
        None where the budget affords neither.
        """
        settings = richer(plan, sim.dt, self.more_modes)
        sibling = self._build(settings)
        full_fits = self.full is not None and self.budget.affords(
            DOUBLING_WORK * work_per_second(self.full(math.inf, sample_s)) * self.window_s)
        if not (full_fits or self._affords(sibling)):
            return None
        self._sibling, self._measured = None, {}
        if full_fits:
            found = self._converged_full_run(sample_s, samples)
            if found is not None:
                return found, 'the full run'
            if not self._affords(sibling):
                return None
        reference = trajectory(sibling, sample_s, samples)
        self.budget.charge(sibling, samples * sample_s)
        self._sibling = (settings, sibling.dt)
        if reference is None:
            raise ValueError('modal.auto cannot measure a plan for this scene: the full run is '
                             'beyond its pilot budget and the richer modal plan diverges; run '
                             'it with method full')
        if self.full is not None and not self._start_sought:
            self._start_sought = True
            self._start = full_run_start(self.full, sample_s, samples,
                                         REFERENCE_ACCURACY * self.tolerance,
                                         min(REFERENCE_WORK, self.budget.remaining_us))
            if self._start is not None:
                self.budget.charge(self.full(math.inf, sample_s),
                                   DOUBLING_WORK * len(self._start) * sample_s)
        if self._start is None:
            return reference, 'a richer plan'
        return reference, (f'a richer plan and the full run over its first '
                           f'{len(self._start) * sample_s:.2g} s')

    def _converged_full_run(self, sample_s: float, samples: int) -> np.ndarray | None:
        """Return the full run's converged trajectory, or None beyond ``REFERENCE_WORK``."""
        found = converged_trajectory(lambda dt: self.full(dt, sample_s),
                                     self.full(math.inf, sample_s).dt, sample_s, samples,
                                     REFERENCE_ACCURACY * self.tolerance, min(
                                         REFERENCE_WORK, self.budget.remaining_us) / self.window_s,
                                     lambda sim: self.budget.charge(sim, samples * sample_s),
                                     self._stepped)
        if found is None:
            return None
        reference, self._reference_dt = found
        return reference

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
                  f'{error:.2%}' if error > self.tolerance else
                  f'cheaper: the plan needs {ratio:.2g} x its work')
        return full, dataclasses.replace(report, error=full_error, method='full', cost_ratio=1.0,
                                         reason=reason, against=full_against,
                                         head_start=head_start(self._stepped, full)
                                         ).as_checked(self._checked)

    def _full_candidate(self, against: str, error: float) -> tuple[Simulation, float, str]:
        """
        Return the full run as a candidate, its error, and what that was measured against.

        Against the pilot's reference down to its step, never below the one the modes predict
        where the window confirms it (:func:`~.full_candidate.at_predicted_step`; against a
        richer sibling as the plan is: priced at the sibling's step unmeasured, a full run
        that met the tolerance at five times the step looked three times dearer than a plan it
        cost a sixth of), unless the plan never came within the tolerance: then the sibling is
        no reference, and the full run is measured by its own step doubling
        (:func:`~.full_candidate.by_step_doubling`). Once the budget is spent, as where no
        plan is made (:func:`~.unplanned_full.unplanned_full`).
        """
        sample_s, samples, reference, _ = self._sampling
        budget = PILOT_MARGIN * self.tolerance
        longest = self.full(math.inf, sample_s)
        if not self.budget.affords(REFERENCE_RUNS * work_per_second(longest) * self.window_s):
            # the budget is spent: the converged reference's step, or a check within what is left
            if against == 'the full run':
                return (self.full(self._reference_dt * (1.0 + 1e-9), sample_s),
                        REFERENCE_ACCURACY * self.tolerance, BY_ITSELF)
            full, report = unplanned_full(self.full, self.budget, self.full_dt[0],
                                          self.window_s, self.horizon_s, self.tolerance,
                                          PILOT_MARGIN, SAMPLES, 'the budget was spent',
                                          self.full_dt[1], saving_pays=False)
            self._checked = report
            return full, report.error, report.against
        if against != 'the full run' and error > self.tolerance:
            full, full_error = by_step_doubling(self.full, sample_s, samples, self.horizon_s,
                                                budget, REFERENCE_WORK / self.window_s,
                                                stepped=self._stepped)
            return full, full_error, BY_ITSELF
        shortest = self._reference_dt if against == 'the full run' else self._sibling[1]
        full, error, window = at_predicted_step(
            self.full, lambda sim: self._error(sim, reference, sample_s, stepped=self._stepped),
            lambda sim: self._measured[id(sim)][1], sample_s, budget, shortest, self.full_dt[1],
            samples * sample_s)
        if math.isfinite(window):     # the modes' prediction, confirmed over the window
            self._checked = PilotReport(error, math.nan, samples * sample_s, against, (), 'full',
                                        1.0, horizon_s=self.horizon_s, window_error=window,
                                        predicted=True)
        return full, error, against

"""
Measure, then trust: the automatic plan's error measured by a pilot run before it is used.

The automatic choice (:mod:`~modal_spring_ros.core.mode_selection`,
:mod:`~modal_spring_ros.core.basis_choice`) *predicts* the error of a plan (modes, basis,
forces, step). A prediction is a model of the error, and on a scene it was not tuned on it can
be wrong many times over. Adaptive ODE solvers never trust a step until a second estimate says
it is good; this module does the same for a whole plan:

1. **A pilot window** that excites what the scene excites (released under gravity from rest,
   its clamp drive) and lasts a few periods of the slowest kept mode and of the drive
   (``MIN_WINDOW_S`` to ``MAX_WINDOW_S``).
2. **A reference** for that window: the full physical run (every DOF, every spring, explicit at
   a converged step) where the band keeps everything and its cost is
   within ``REFERENCE_WORK``; otherwise the richer sibling of the plan (an embedded pair: every
   spring on every step, the derivatives basis with twice the directions, twice the modes the
   band allows, half the step).
3. **The measured error**: relative L2 of the free-DOF displacement in the clamp's frame over
   the window's samples, against the reference (as the benchmark measures it).
4. **Refinement**: while the error is above ``PILOT_MARGIN`` of the tolerance, each refinement
   the plan still has (exact forces, the derivatives basis, more derivative directions, more
   modes, half the step) is tried alone and the one that measures lowest is kept (the cheaper
   one on a near tie), for at most ``MAX_ROUNDS`` rounds.
5. **The full run is a candidate**: where the band keeps every mode, the full run meets any
   tolerance, and its cost per simulated second is compared with the plan's by a work model
   fitted to measured step costs (deterministic: the same choice whatever the machine's load
   or thread count). The cheaper
   of the two that meets the tolerance is chosen; a plan that cannot be brought within the
   tolerance falls back to the full run, and says so.

Everything here is deterministic: no wall-clock time enters a decision.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Callable

from modal_spring_ros.core.model import MassSpringModel
from modal_spring_ros.core.simulations import DivergenceError, Simulation
import numpy as np

#: The measured error must be within this share of the tolerance (a margin for what the pilot
#: window does not see).
PILOT_MARGIN = 0.8
#: Most refinement rounds before the plan gives way to the full run.
MAX_ROUNDS = 5
#: Pilot window bounds, s, and how many periods of the slowest kept mode and of the drive it spans
#: (a drive near a resonance builds its error up over several periods).
MIN_WINDOW_S, MAX_WINDOW_S, WINDOW_PERIODS = 1.0, 3.0, 8.0
#: Samples of the displacement over the window (at least).
SAMPLES = 120
#: The full reference run is used when its window costs at most this much modelled CPU time, us.
REFERENCE_WORK = 5e6
#: First step of the full reference run: at most this share of its explicit stability limit,
#: and this many times shorter than the plan's (then halved until it has converged).
REFERENCE_SAFETY, REFERENCE_REFINEMENT = 0.15, 4.0
#: The reference's own error (by step doubling) must be within this share of the tolerance.
REFERENCE_ACCURACY = 0.1
#: Most derivative directions a refinement asks for.
MAX_PILOT_DIRECTIONS = 96
#: The work model, in microseconds of one core (fitted to per-step CPU times of full and modal
#: runs from 2 to 40,000 springs, single-threaded BLAS): a step's fixed cost (full, modal), per
#: spring evaluated, per free DOF of a full step, per free DOF and stepped coordinate (the two
#: products with the shapes), and per pair of coordinates (a refreshed step's tangent).
STEP_US = {'full': 60.0, 'modal': 45.0}
SPRING_US, DOF_US, PROJECTION_US, TANGENT_US = 0.02, 0.02, 0.001, 0.0005
#: A turning clamp's step also computes the frame's motion and its inertial loads.
TURNING_STEP_US = 140.0
#: A candidate within this factor of another's measured error counts as a tie (cheaper wins).
TIE = 1.1


@dataclasses.dataclass(frozen=True)
class PlanSettings:
    """What an automatic plan sets: modes (up to ``highest_hz``), basis, forces, step."""

    highest_hz: float
    basis_kind: str
    directions: int
    forces: str
    refresh: int
    dt: float

    def describe(self) -> str:
        forces = (f'springs every {self.refresh} steps' if self.forces == 'refreshed'
                  else f'{self.forces} forces')
        basis = (f'derivatives basis ({self.directions} directions)'
                 if self.basis_kind == 'derivatives' else 'rest modes')
        return f'modes up to {self.highest_hz:.4g} Hz, {basis}, {forces}, dt {self.dt:.3g} s'


@dataclasses.dataclass(frozen=True)
class PilotReport:
    """What the pilot measured, against what, and what it chose."""

    error: float                    # measured relative error of the chosen plan (0: full run)
    planned_error: float            # measured error of the plan as first predicted
    window_s: float
    against: str                    # 'the full run' or 'a richer plan'
    refined: tuple[str, ...]        # refinements applied, in order
    method: str                     # 'modal' or 'full'
    cost_ratio: float               # chosen plan's work per simulated second / the full run's
    reason: str = ''                # why the full run was chosen, when it was

    def describe(self) -> str:
        if self.method == 'full':
            return (f'full run chosen ({self.reason}); the modal plan measured '
                    f'{self.planned_error:.2%} against {self.against} over {self.window_s:.3g} s')
        steps = f", refined: {', '.join(self.refined)}" if self.refined else ''
        return (f'measured error {self.error:.2%} against {self.against} over '
                f'{self.window_s:.3g} s (pilot){steps}; work {self.cost_ratio:.2g} x the full '
                'run')


def pilot_window(model: MassSpringModel, lowest_hz: float) -> float:
    """Return the pilot window: a few periods of the slowest kept mode and of the drive."""
    drive = model.scene.anchor_motion.frequencies_hz
    slowest = min([lowest_hz, *[f for f in drive.tolist() if f > 0]])
    window = WINDOW_PERIODS / slowest if slowest > 0 else MAX_WINDOW_S
    return float(min(MAX_WINDOW_S, max(MIN_WINDOW_S, window)))


def work_per_second(sim: Simulation) -> float:
    """
    Return the modelled CPU time ``sim`` takes per simulated second, us (see ``STEP_US``).

    Deterministic (no clock is read), so that the same scene and settings give the same plan on
    any machine and under any load. A sampled plan is taken to evaluate about four springs per
    coordinate (its sample is trained only once the plan is chosen).
    """
    model = sim.model
    springs = model.scene.n_springs
    turning = TURNING_STEP_US if model.rotates else 0.0
    if sim.method == 'full':
        per_step = STEP_US['full'] + turning + SPRING_US * springs + DOF_US * model.n_free_dof
        return per_step / sim.dt
    coords = sim.coordinates
    if getattr(sim, 'sample_tolerance', None) is not None:
        evaluated = float(min(springs, 4 * coords))
        per_step = (STEP_US['modal'] + turning + SPRING_US * evaluated
                    + PROJECTION_US * evaluated * 2 * model.dimension * coords)
    else:
        evaluation = SPRING_US * springs + PROJECTION_US * model.n_free_dof * coords
        tangent = TANGENT_US * coords * coords if sim.force_refresh > 1 else 0.0
        per_step = STEP_US['modal'] + turning + evaluation / sim.force_refresh + tangent
    return per_step / sim.dt


def trajectory(sim: Simulation, sample_s: float, samples: int) -> np.ndarray | None:
    """Return the displacement every ``sample_s`` from rest, or None where the run diverges."""
    per = max(1, int(round(sample_s / sim.dt)))
    out = np.empty((samples, sim.model.n_free_dof))
    sim.reset()
    try:
        for k in range(samples):
            sim.step(per)
            out[k] = sim.displacement()
    except DivergenceError:
        return None
    finally:
        sim.reset()
    return out if np.isfinite(out).all() else None


def trajectory_error(run: np.ndarray | None, reference: np.ndarray) -> float:
    """Relative L2 error of a trajectory against the reference (inf where it diverged)."""
    if run is None:
        return math.inf
    norm = float(np.linalg.norm(reference))
    return float(np.linalg.norm(run - reference)) / norm if norm > 0 else 0.0


def converged_trajectory(run_at: Callable[[float], Simulation], step: float, sample_s: float,
                         samples: int, accuracy: float, work_per_s: float = math.inf
                         ) -> tuple[np.ndarray, float] | None:
    """
    Return a run's trajectory converged in its step, and the finer step it was computed at.

    ``run_at(dt)`` builds the run at a step no longer than ``dt`` (landing on the samples).
    Step doubling: a second-order scheme's error at ``h / 2`` is about a third of the
    difference between its runs at ``h`` and ``h / 2``; the step is halved from ``step`` until
    that is within ``accuracy`` (relative), and the Richardson extrapolation of the last two is
    returned. None when it diverges, or when the modelled work of the runs so far passes
    ``work_per_s`` (us per simulated second, summed over the runs).
    """
    spent, coarse = 0.0, None
    while True:
        sim = run_at(step)
        spent += work_per_second(sim)
        if spent > work_per_s:
            return None
        fine = trajectory(sim, sample_s, samples)
        if fine is None:
            return None
        if coarse is not None and trajectory_error(coarse, fine) / 3.0 <= accuracy:
            return (4.0 * fine - coarse) / 3.0, sim.dt
        coarse, step = fine, sim.dt / 2.0


class Pilot:
    """
    Refine a plan by measurement and choose between it and the full run.

    ``make(settings)`` builds the modal run of a plan; ``full(longest_dt, sample_s)`` the full
    run at a step no longer than ``longest_dt`` that lands on the samples (None when the band
    does not keep every mode: the full run is then neither reference nor candidate);
    ``more_modes(hz)`` the next mode limit above ``hz`` the band allows (None: none);
    ``can_halve_step``: the step is the plan's to choose (not given by the user).
    """

    def __init__(self, model: MassSpringModel, tolerance: float,
                 make: Callable[[PlanSettings], Simulation],
                 full: Callable[[float, float], Simulation] | None,
                 more_modes: Callable[[float], float | None], lowest_hz: float,
                 can_halve_step: bool = True):
        self.model = model
        self.can_halve_step = can_halve_step
        self.tolerance = float(tolerance)
        self.make = make
        self.full = full
        self.more_modes = more_modes
        self.window_s = pilot_window(model, lowest_hz)

    def run(self, plan: PlanSettings) -> tuple[Simulation, PilotReport]:
        """Return the simulation chosen and what the pilot measured."""
        sim = self.make(plan)
        sample_s = sim.dt * max(1, int(round(self.window_s / SAMPLES / sim.dt)))
        samples = max(1, int(math.ceil(self.window_s / sample_s)))
        reference, against = self._reference(plan, sim, sample_s, samples)
        budget = PILOT_MARGIN * self.tolerance
        error = planned = trajectory_error(trajectory(sim, sample_s, samples), reference)
        refined: list[str] = []
        stale = False     # the plan was refined since its richer sibling was made
        for _ in range(2 * MAX_ROUNDS):
            if error <= budget and stale:
                reference, against, error = self._remeasured(plan, sim, sample_s, samples)
                stale = False
            if error <= budget or len(refined) >= MAX_ROUNDS:
                break
            options = []
            for name, candidate in self._refinements(plan):
                trial = self.make(candidate)
                measured = trajectory_error(trajectory(trial, sample_s, samples), reference)
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
            stale = against != 'the full run'
        if stale:
            reference, against, error = self._remeasured(plan, sim, sample_s, samples)
        self._sampling = (sample_s, samples, reference, against)
        return self._choose(sim, plan, error, planned, against, tuple(refined))

    # -- internals -----------------------------------------------------------------------------
    def _remeasured(self, plan: PlanSettings, sim: Simulation, sample_s: float, samples: int
                    ) -> tuple[np.ndarray, str, float]:
        """
        Measure a refined plan against a sibling richer than *it*.

        A sibling made for the first plan can be the refined plan itself, and would measure 0.
        """
        reference, against = self._reference(plan, sim, sample_s, samples)
        return reference, against, trajectory_error(trajectory(sim, sample_s, samples), reference)

    def _reference(self, plan: PlanSettings, sim: Simulation, sample_s: float, samples: int
                   ) -> tuple[np.ndarray, str]:
        """
        Return the reference for ``plan`` (built as ``sim``): the full run, or a richer sibling.

        The sibling's step is half the step ``sim`` was built with (a plan's step can be cut to
        its stability limit when built: halving the plan's own could give the same run).
        """
        if self.full is not None:
            found = self._converged_full_run(plan, sample_s, samples)
            if found is not None:
                return found, 'the full run'
        richer = dataclasses.replace(
            plan, forces='exact', refresh=1, basis_kind='derivatives',
            directions=min(MAX_PILOT_DIRECTIONS, 2 * plan.directions),
            highest_hz=self.more_modes(plan.highest_hz) or plan.highest_hz,
            dt=min(plan.dt, sim.dt) / 2)
        reference = trajectory(self.make(richer), sample_s, samples)
        if reference is None:
            raise ValueError('modal.auto cannot measure a plan for this scene: the full run is '
                             'beyond its pilot budget and the richer modal plan diverges; run '
                             'it with method full')
        return reference, 'a richer plan'

    def _converged_full_run(self, plan: PlanSettings, sample_s: float, samples: int
                            ) -> np.ndarray | None:
        """Return the full run's converged trajectory, or None beyond ``REFERENCE_WORK``."""
        probe = self.full(plan.dt, sample_s)
        step = min(plan.dt / REFERENCE_REFINEMENT, REFERENCE_SAFETY * probe.stability_limit())
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

    def _choose(self, sim: Simulation, plan: PlanSettings, error: float, planned: float,
                against: str, refined: tuple[str, ...]) -> tuple[Simulation, PilotReport]:
        if self.full is None:
            return sim, PilotReport(error, planned, self.window_s, against, refined, 'modal',
                                    math.nan)
        full, full_error = self._full_candidate(plan, against)
        ratio = work_per_second(sim) / work_per_second(full)
        report = PilotReport(error, planned, self.window_s, against, refined, 'modal', ratio)
        if error <= self.tolerance and ratio < 1.0:
            return sim, report
        reason = (f'no plan within {self.tolerance:.2%} after refining'
                  if error > self.tolerance else f'cheaper: the plan needs {ratio:.2g} x its work')
        return full, dataclasses.replace(report, error=full_error, method='full', cost_ratio=1.0,
                                         reason=reason)

    def _full_candidate(self, plan: PlanSettings, against: str) -> tuple[Simulation, float]:
        """
        Return the full run at the longest step that measures within budget, and its error.

        Steps from the plan's, halved. Against a richer plan (no full reference), the
        reference step.
        """
        sample_s, samples, reference, _ = self._sampling
        if against != 'the full run':
            return self.full(plan.dt / REFERENCE_REFINEMENT, sample_s), 0.0
        shortest = self._reference_dt
        step = plan.dt
        while True:
            full = self.full(step, sample_s)
            error = trajectory_error(trajectory(full, sample_s, samples), reference)
            if error <= PILOT_MARGIN * self.tolerance or step <= shortest:
                return full, error
            step /= 2.0

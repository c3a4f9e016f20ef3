"""
Watch while running: the plan's error measured again, from the run's own state, as it runs.

The pilot (:mod:`~modal_spring_ros.core.auto.pilot`) measures a plan from rest over one window
and extrapolates a drift model to the run's horizon. A run that goes on (a node streams for
hours; users pull, push and drive the clamp into regimes no pilot window saw; an undamped
scene's phase error keeps growing) can leave what the plan follows, and nothing measured at the
start says so. So, every ``interval_s`` of simulated time, the watch takes the run's state and
steps shadow runs from it over one pilot window: a copy of the plan, and the pilot's
reference (the full run at its converged step, or the richer plan with its Richardson share).
Their difference, the relative L2 error of the free-DOF displacement in the clamp's frame over
the window's samples as the pilot measures it, is the plan's error from there on
(:class:`WatchedWindow`). A window beyond the tolerance makes the run fall back, from its state
at that moment, to what the pilot named for it (the full run at the longest step it measured
within the tolerance; the richer plan where the band keeps no full run), and says so.

Each window also steps a third shadow: a twin of the plan from the same state perturbed by a
hair (:mod:`~modal_spring_ros.core.auto.amplification`). Where the motion amplifies its
differences (a chaotic one: a soft solid turned far, a skin crumpling), no run keeps to another
within the tolerance for long, the full run's included: the window says so
(:attr:`WatchedWindow.amplifying`), the run is not fallen back (no other run would hold the
tolerance either), and the error printed for it does not hold. Where the pilot chose the full
run, the run is watched by its twin alone (:func:`twin_reference`), where that costs at most
``TWIN_SHARE`` of the run.

The shadows step in slices (:meth:`RunWatch.advance` takes a wall-clock deadline), so that a
caller that streams frames steps them in its idle time between two frames, on its own thread:
they share the run's model and basis, which are read, never written, while stepping. A clamp
that follows poses has a state of its own that a shadow would advance: such a run is not watched
(:func:`watchable`). Nothing here reads a clock to decide anything: the same run gives the same
windows and the same fallback on any machine.
"""
from __future__ import annotations

import dataclasses
import math
import time
from typing import Callable, Mapping

from modal_spring_ros.core.auto.amplification import (amplifies, describe_rate, Growth,
                                                      perturbed, SAMPLES as TWIN_SAMPLES,
                                                      twin_samples, UNBOUNDED,
                                                      WINDOW_S as TWIN_WINDOW_S)
from modal_spring_ros.core.auto.measured_error import on_samples
from modal_spring_ros.core.auto.work_model import work_per_second
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.motion.anchor_motion import AnchorMotion
from modal_spring_ros.core.simulations import DivergenceError, RunState, Simulation
import numpy as np

#: Simulated seconds between the starts of two watched windows, by default.
DEFAULT_INTERVAL_S = 10.0
#: Watching at the default interval costs at most this share of the run's own (modelled) work:
#: the interval is lengthened where the shadow runs cost more than that over it.
WORK_SHARE = 0.25
#: A full run the pilot chose is watched by its twin alone (over ``TWIN_WINDOW_S`` on
#: ``TWIN_SAMPLES`` samples) in a run where its two shadows cost at most this share of it.
TWIN_SHARE = 0.1


def watchable(model: MassSpringModel) -> bool:
    """Tell whether a run of ``model`` can be watched (its clamp moves as a function of time)."""
    return isinstance(model.motion, AnchorMotion)


def watch_of(sim: Simulation, interval_s: float | None, budget: float | None = None,
             run_s: float | None = None, from_s: float = 0.0) -> 'RunWatch | None':
    """
    Return a watch of ``sim`` (see :class:`RunWatch`), or None.

    ``interval_s`` None: every ``DEFAULT_INTERVAL_S``, or less often where watching would cost
    more than ``budget`` (by default ``WORK_SHARE`` of the plan's work). ``run_s``: the run's
    length, where it has one (a run longer than the pilot's window is watched at least once),
    watched from ``from_s`` on (a run that went on from where its pilot's run ended).
    None is returned for a run that is not an automatic plan, an interval of 0, or a clamp
    that follows poses. A run watched by its twin alone is not watched in a run of ``run_s``
    where one window would cost more than ``TWIN_SHARE`` of it.
    """
    reference = sim.watch_reference
    if reference is None or interval_s == 0.0 or not watchable(sim.model):
        return None
    if (reference.reference is None and run_s is not None
            and reference.window_s * reference.shadow_work
            > TWIN_SHARE * reference.plan_work * run_s):
        run_s = None
    left = None if run_s is None else run_s - from_s
    if interval_s is not None:
        return RunWatch(reference, interval_s, run_s=left)
    if budget is None:
        budget = WORK_SHARE * reference.plan_work
    return RunWatch(reference, DEFAULT_INTERVAL_S, budget, left)


def twin_reference(sim: Simulation, tolerance: float) -> 'WatchReference':
    """
    Return what the full run ``sim`` the pilot chose is watched against: its twin alone.

    Its step's error was measured over its start, and the step the pilot found is what a
    fallback would take: the watch measures only whether the motion amplifies its differences.
    """
    work = work_per_second(sim)
    return WatchReference(None, None, {}, '', TWIN_WINDOW_S / TWIN_SAMPLES, TWIN_SAMPLES, 1.0,
                          tolerance, work, 2.0 * work)


@dataclasses.dataclass(frozen=True)
class WatchReference:
    """
    What a plan is watched against, as its pilot measured it.

    ``reference()`` builds the reference run at rest, on the sample grid (None: the plan is
    watched by its twin alone, :func:`twin_reference`, and has no fallback); ``fallback()``
    what the run falls back to, and ``fallback_settings`` the same as the
    :class:`~modal_spring_ros.core.config.SimulationConfig` fields that rebuild it (a node
    falls back by setting its parameters, so that they say what runs); ``shared`` the
    Richardson factor of a richer plan's step (1 against the full run); ``plan_work`` and
    ``shadow_work`` the plan's and its shadows' modelled work, us per simulated second.
    """

    reference: Callable[[], Simulation] | None
    fallback: Callable[[], Simulation] | None
    fallback_settings: Mapping[str, object]
    against: str
    sample_s: float
    samples: int
    shared: float
    tolerance: float
    plan_work: float
    shadow_work: float

    @property
    def window_s(self) -> float:
        return self.samples * self.sample_s


@dataclasses.dataclass(frozen=True)
class WatchedWindow:
    """
    One watched window: the plan's error from the run's state at ``start_s`` on.

    ``growth``: how fast a hair's difference grew over it, e-folds per second
    (:mod:`~modal_spring_ros.core.auto.amplification`). ``against`` empty: a window of the twin
    alone (no error measured).
    """

    start_s: float
    window_s: float
    error: float            # relative L2; inf: the plan diverged; nan: the reference did
    tolerance: float
    against: str
    growth: float = math.nan

    @property
    def measured(self) -> bool:
        return not math.isnan(self.error)

    @property
    def amplifying(self) -> bool:
        """Tell whether the motion amplified its differences here: its error is not bounded."""
        return amplifies(self.growth)

    @property
    def within(self) -> bool:
        """Tell whether the plan met its tolerance (unmeasured and twin-only windows have)."""
        return not self.against or not self.measured or self.error <= self.tolerance

    def describe(self) -> str:
        span = f'over {self.window_s:.3g} s from t = {self.start_s:.4g} s'
        amplified = f': {UNBOUNDED}' if self.amplifying else ''
        if not self.against:
            return f'{describe_rate(self.growth)} {span}{amplified}'
        span = f'{span} against {self.against}'
        amplified = f'; {describe_rate(self.growth)}{amplified}' if self.amplifying else ''
        if not self.measured:
            return f'not measured {span}: the reference diverged{amplified}'
        if math.isinf(self.error):
            return f'the plan diverged {span}{amplified}'
        return f'{self.error:.2%} {span}{amplified}'


class _Shadow:
    """
    The plan's copy, the reference and the plan's twin, from one state, stepped sample by sample.

    ``runs``: the plan's copy, the reference (where the watch has one) and the twin, built once
    per watch and taken over to each window's state (the twin's perturbed by a hair; stepped
    over the window's first ``TWIN_WINDOW_S`` only).
    """

    def __init__(self, plan: Simulation, runs: list[Simulation], reference: WatchReference):
        state = RunState.of(plan)
        self.start_s = state.time
        self.reference = reference
        self._runs = runs
        for run in runs[:-1]:
            run.take_over(state)
        runs[-1].take_over(perturbed(state))
        self._per = [max(1, int(round(reference.sample_s / run.dt))) for run in self._runs]
        self._growth = Growth(self._per[0] * runs[0].dt)
        self._twin_samples = twin_samples(reference.sample_s, reference.samples)
        self._done = 0
        self._difference = self._motion = 0.0
        self.result: WatchedWindow | None = None

    def advance(self, deadline: float) -> bool:
        """Step whole samples until the window is done (True) or past ``deadline`` (monotonic)."""
        ref = self.reference
        while self.result is None:
            try:
                plan = self._sample(0)
            except DivergenceError:
                return self._finish(math.inf)
            if ref.reference is not None:
                try:
                    truth = self._sample(1)
                except DivergenceError:
                    return self._finish(math.nan)
                self._difference += float(np.sum((plan - truth) ** 2))
                self._motion += float(truth @ truth)
            if self._done < self._twin_samples and not self._growth.diverged:
                try:
                    self._growth.add(plan, self._sample(len(self._runs) - 1))
                except DivergenceError:
                    self._growth.diverged = True
            self._done += 1
            if self._done >= ref.samples:
                error = (math.nan if ref.reference is None
                         else math.sqrt(self._difference / self._motion) * ref.shared
                         if self._motion > 0.0 else 0.0)
                return self._finish(error)
            if time.monotonic() >= deadline:
                return False
        return True

    def _sample(self, which: int) -> np.ndarray:
        run = self._runs[which]
        run.step(self._per[which])
        u = run.displacement()
        if not np.isfinite(u).all():
            raise DivergenceError('non-finite state', run.time, run.steps)
        return u

    def _finish(self, error: float) -> bool:
        ref = self.reference
        self.result = WatchedWindow(self.start_s, ref.window_s, error, ref.tolerance,
                                    ref.against, self._growth.rate())
        return True


class RunWatch:
    """
    Watch one run: a shadow window every ``interval_s`` of simulated time, from its state.

    The caller steps the run, and between steps calls :meth:`advance` (with the run and a
    deadline); a finished window is returned once, kept as :attr:`last` and :attr:`worst`, and
    when it is beyond the tolerance :meth:`fallback` builds what the run continues as.
    """

    def __init__(self, reference: WatchReference, interval_s: float = DEFAULT_INTERVAL_S,
                 budget: float | None = None, run_s: float | None = None):
        """
        Watch every ``interval_s`` of simulated time, or less often within ``budget``.

        ``budget``: the work watching may cost, us per simulated second (modelled; None: any).
        ``run_s``: the run's length (None: it streams until stopped). A run longer than one
        window is watched at least once: its first window starts no later than one window
        before its end (the pilot measured the first window from rest; this one starts from
        the state the run has reached, and ends with the run).
        """
        if not (math.isfinite(interval_s) and interval_s > 0.0):
            raise ValueError(f'watch interval ({interval_s}) must be a positive number of '
                             'seconds')
        self.reference = reference
        #: the interval, lengthened so that watching costs at most ``budget``
        self.interval_s = float(interval_s)
        if budget is not None:
            self.interval_s = max(self.interval_s, reference.window_s * reference.shadow_work
                                  / budget if budget > 0.0 else math.inf)
        #: when the first window starts, after the run's start (or a restart)
        self.first_s = self.interval_s
        if run_s is not None and run_s > reference.window_s * (1.0 + 1e-9):
            self.first_s = min(self.interval_s, run_s - reference.window_s)
        self._next: float | None = None   # when the next window starts (None: the first)
        self._shadow: _Shadow | None = None
        self._runs: list[Simulation] | None = None    # the plan's copy and the reference
        self.windows = 0
        self.last: WatchedWindow | None = None
        self.worst: WatchedWindow | None = None
        #: the first window where the motion amplified its differences
        self.amplifying: WatchedWindow | None = None

    @property
    def busy(self) -> bool:
        """Tell whether a window is being stepped."""
        return self._shadow is not None

    def advance(self, sim: Simulation, deadline: float = math.inf) -> WatchedWindow | None:
        """
        Start a window when one is due, step the one under way; return it once it is done.

        ``deadline``: monotonic time at which to hand back (the window goes on at the next call).
        """
        if self._shadow is None:
            if self._next is None:      # the pilot measured the first window from rest
                self._next = sim.time + self.first_s
            if sim.time + 0.5 * sim.dt < self._next:
                return None
            if self._runs is None or self._runs[0].method != sim.method:
                make = self.reference.reference
                self._runs = ([sim.with_dt(sim.dt)] + ([make()] if make is not None else [])
                              + [sim.with_dt(sim.dt)])
            self._shadow = _Shadow(sim, self._runs, self.reference)
            self._next = sim.time + self.interval_s
        if not self._shadow.advance(deadline):
            return None
        window, self._shadow = self._shadow.result, None
        self.windows += 1
        self.last = window
        if window.measured and (self.worst is None or not window.error <= self.worst.error):
            self.worst = window
        if window.amplifying and self.amplifying is None:
            self.amplifying = window
        return window

    def restart(self) -> None:
        """
        Drop the window under way and watch again as from a start (a reset, a band change).

        The plan's copy is made again from the run's state then.
        """
        self._shadow = self._runs = self._next = None

    def before_step(self, sim: Simulation, sample_s: float | None = None
                    ) -> tuple[Simulation, WatchedWindow | None]:
        """
        Advance the watch all the way before a step of ``sim`` (a run that is not streamed).

        Return the run that goes on (the fallback, from ``sim``'s state, where a window was
        beyond the tolerance: see :meth:`fallback`) and the window finished, or None.
        """
        window = self.advance(sim)
        if window is None or window.within:
            return sim, window
        return self.fallback(sim, sample_s), window

    def fallback(self, sim: Simulation, sample_s: float | None = None) -> Simulation:
        """
        Return what ``sim`` falls back to, continuing from its state and time.

        At a step that divides ``sample_s`` (a recording's frame interval) when given.
        """
        fallback = self.reference.fallback()
        if sample_s is not None:
            fallback = on_samples(fallback, sample_s)
        fallback.take_over(sim)
        return fallback

    def describe(self) -> str:
        """Say what was watched: how many windows, the last and the largest error."""
        if self.last is None:
            against = (f'against {self.reference.against}' if self.reference.against
                       else 'of its twin moved by a hair')
            return (f'every {self.interval_s:.3g} s of the run: a {self.reference.window_s:.3g} '
                    f's window {against} (none yet)')
        worst = f'; largest {self.worst.describe()}' if self.worst not in (None, self.last) else ''
        amplified = (f'; amplifying first {self.amplifying.describe()}'
                     if self.amplifying not in (None, self.last) else '')
        count = f"{self.windows} window{'s' if self.windows > 1 else ''}"
        return f'{count}: last {self.last.describe()}{worst}{amplified}'

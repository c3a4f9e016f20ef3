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
hair (:mod:`~modal_spring_ros.core.auto.watch.amplification`). Where the motion amplifies its
differences (a chaotic one: a soft solid turned far, a skin crumpling), no run keeps to another
within the tolerance for long, the full run's included: the window says so
(:attr:`WatchedWindow.amplifying`), the run is not fallen back (no other run would hold the
tolerance either), and the error printed for it does not hold. Where the pilot chose the full
run, the run is watched by its twin alone (:mod:`~.twin_watch`), over a window that costs at
most ``TWIN_SHARE`` of the run: stepped beside the run itself where the caller steps the run
one step at a time (:meth:`RunWatch.before_step`, :class:`~.amplification.TwinBeside`), the
run being its own copy.

The shadows step in slices (:meth:`RunWatch.advance` takes a wall-clock deadline), so that a
caller that streams frames steps them in its idle time between two frames, on its own thread:
they share the run's model and basis, which are read, never written, while stepping. A clamp
that follows poses has a state of its own that a shadow would advance: such a run is not watched
(:func:`watchable`). Nothing here reads a clock to decide anything: the same run gives the same
windows and the same fallback on any machine.

Between windows, a plan's watch keeps a sentinel (:mod:`~modal_spring_ros.core.auto.watch.
sentinel`): a window starts at once where the run's motion outgrows twice the largest a window
measured, or where the run took an input no window measured (:meth:`RunWatch.took_input`: a
user's pull in the node); a window within the promise whose error is heading beyond the
tolerance (:attr:`WatchedWindow.rising`) is followed at once by the next. A window is within
the promise when its error is within the tolerance and its worst quarter second within
``WINDOW_ALLOWANCE`` times it.
"""
from __future__ import annotations

import math
from typing import Callable

from modal_spring_ros.core.auto.measured_error import on_samples
from modal_spring_ros.core.auto.watch.amplification import (MIN_SAMPLES as TWIN_MIN_SAMPLES,
                                                            twin_samples, TwinBeside)
from modal_spring_ros.core.auto.watch.sentinel import Sentinel
from modal_spring_ros.core.auto.watch.shadows import Shadows
from modal_spring_ros.core.auto.watch.twin_watch import (SHORTEST_TWIN_S, TWIN_SHARE,
                                                         twin_watched, watchable, within_share)
from modal_spring_ros.core.auto.watch.windows import WatchedWindow, WatchReference
from modal_spring_ros.core.simulations import Simulation

#: Simulated seconds between the starts of two watched windows, by default.
DEFAULT_INTERVAL_S = 10.0
#: Watching at the default interval costs at most this share of the run's own (modelled) work:
#: the interval is lengthened where the shadow runs cost more than that over it.
WORK_SHARE = 0.25
#: Why a window started before it was due, where the run took an input (:meth:`took_input`).
TOOK_INPUT = 'the run took an input no window measured'
#: ... and where the window before it was heading beyond the tolerance.
HEADING = "the last window's error heading beyond the tolerance"


def watch_of(sim: Simulation, interval_s: float | None, budget: float | None = None,
             run_s: float | None = None, from_s: float = 0.0) -> 'RunWatch | None':
    """
    Return a watch of ``sim`` (see :class:`RunWatch`), or None.

    ``interval_s`` None: every ``DEFAULT_INTERVAL_S``, or less often where watching would cost
    more than ``budget`` (by default ``WORK_SHARE`` of the plan's work). ``run_s``: the run's
    length, where it has one (a run longer than the pilot's window is watched at least once),
    watched from ``from_s`` on (a run that went on from where its pilot's run ended).
    None is returned for a run that is not an automatic plan, an interval of 0, or a clamp
    that follows poses. A run watched by its twin alone is watched over a window that costs at
    most ``TWIN_SHARE`` of a run of ``run_s`` (:func:`within_share`; a run of given length is
    stepped one step at a time: its twin beside it costs the twin alone), and not where that
    window would be shorter than ``SHORTEST_TWIN_S``.
    """
    reference = sim.watch_reference
    if reference is None or interval_s == 0.0 or not watchable(sim.model):
        return None
    dear = False
    if reference.reference is None and run_s is not None:
        within = within_share(reference, run_s)
        dear, reference = within is None, within or reference
    left = None if run_s is None else run_s - from_s
    if interval_s is not None:
        return RunWatch(reference, interval_s, run_s=left, at_least_once=not dear)
    if budget is None:
        budget = WORK_SHARE * reference.plan_work
    return RunWatch(reference, DEFAULT_INTERVAL_S, budget, left, at_least_once=not dear)


class RunWatch:
    """
    Watch one run: a shadow window every ``interval_s`` of simulated time, from its state.

    The caller steps the run, and between steps calls :meth:`advance` (with the run and a
    deadline); a finished window is returned once, kept as :attr:`last` and :attr:`worst`, and
    when it is beyond the tolerance :meth:`fallback` builds what the run continues as.
    """

    def __init__(self, reference: WatchReference, interval_s: float = DEFAULT_INTERVAL_S,
                 budget: float | None = None, run_s: float | None = None,
                 at_least_once: bool = True):
        """
        Watch every ``interval_s`` of simulated time, or less often within ``budget``.

        ``budget``: the work watching may cost, us per simulated second (modelled; None: any).
        ``run_s``: the run's length (None: it streams until stopped). A run longer than one
        window is watched at least once (``at_least_once``; not where a twin's window within
        ``TWIN_SHARE`` of it would be shorter than ``SHORTEST_TWIN_S``: :func:`watch_of`): its
        first window starts no later than one window before its end (the pilot measured the
        first window from rest; this one starts from the state the run has reached, and ends
        with the run).
        """
        if not (math.isfinite(interval_s) and interval_s > 0.0):
            raise ValueError(f'watch interval ({interval_s}) must be a positive number of '
                             'seconds')
        self.reference = reference
        #: the interval, lengthened so that watching costs at most ``budget``
        self.interval_s = float(interval_s)
        #: the interval asked for (None: the default, within ``budget``)
        self.asked_s = float(interval_s) if budget is None else None
        #: the shortest interval ``budget`` affords (an input's window waits for it)
        self.least_s = 0.0
        if budget is not None:
            self.least_s = (reference.window_s * reference.shadow_work / budget if budget > 0.0
                            else math.inf)
            self.interval_s = max(self.interval_s, self.least_s)
        #: when the first window starts, after the run's start (or a restart)
        self.first_s, self.run_s, self.at_least_once = self.interval_s, run_s, at_least_once
        if at_least_once and run_s is not None and run_s > reference.window_s * (1.0 + 1e-9):
            self.first_s = min(self.interval_s, run_s - reference.window_s)
        self._next: float | None = None   # when the next window starts (None: the first)
        self._measured_until = -math.inf   # the end of the span the last window measures
        self._input = False                 # the run took an input no window measured
        self._heading = False               # the last window's error was heading beyond
        self._started = -math.inf           # when the last window started
        self._began: float | None = None    # when the watch began (its first call)
        #: the watch of the run this one fell back to (:meth:`after_fallback`), or None
        self.then: RunWatch | None = None
        #: starts a window where the run's motion outgrows what was measured (a plan's watch)
        self.sentinel = (Sentinel(reference.sample_s, reference.window_s)
                         if reference.reference is not None else None)
        self._shadow: Shadows | None = None
        self._beside: TwinBeside | None = None         # a twin stepped beside the run itself
        self._runs: list[Simulation] | None = None    # the shadows, kept from window to window
        self.windows = 0
        self.last: WatchedWindow | None = None
        self.worst: WatchedWindow | None = None
        #: the first window where the motion amplified its differences
        self.amplifying: WatchedWindow | None = None

    @property
    def busy(self) -> bool:
        """Tell whether a window is being stepped."""
        return self._shadow is not None or self._beside is not None

    def _due(self, sim: Simulation) -> str | None:
        """
        Return why a window starts now, or None (the first one's start set on the first call).

        It is due, the run took an input (:meth:`took_input`), or its motion outgrew what the
        windows (the pilot's from the watch's start, as from rest) measured (:mod:`~.sentinel`).
        """
        if self._next is None:          # the pilot measured the first window from rest
            self._next = sim.time + self.first_s
            self._began = sim.time if self._began is None else self._began
            self._measured_until = sim.time + self.reference.window_s
        outgrown = (self.sentinel is not None and sim.time + 0.5 * sim.dt >= self.sentinel.next_s
                    and self.sentinel.outgrown(sim, self._measured(sim)))  # once a sample
        took = self._input and sim.time + 0.5 * sim.dt >= self._started + self.least_s
        if not (outgrown or took) and sim.time + 0.5 * sim.dt < self._next:
            return None
        self._next, self._started = sim.time + self.interval_s, sim.time
        self._measured_until = sim.time + self.reference.window_s
        cause = (self.sentinel.describe_beyond() if outgrown else TOOK_INPUT if took
                 else HEADING if self._heading else '')
        self._input = self._heading = False
        return cause

    def _measured(self, sim: Simulation) -> bool:
        """Tell whether ``sim`` is within the span the last window (or the pilot's) measures."""
        return sim.time <= self._measured_until + 0.5 * sim.dt

    def _kept(self, sim: Simulation, make: Callable[[], list[Simulation]]) -> list[Simulation]:
        """Return the shadows kept from the last window where they step as ``sim`` does."""
        if self._runs is None or self._runs[0].method != sim.method:
            self._runs = make()
        return self._runs

    def _finished(self, window: WatchedWindow) -> WatchedWindow:
        if window.rising:          # watched on from where it ended, until caught or back within
            self._next, self._heading = min(self._next, self._measured_until), True
        self.windows += 1
        self.last = window
        if window.measured and (self.worst is None or not window.error <= self.worst.error):
            self.worst = window
        if window.amplifying and self.amplifying is None:
            self.amplifying = window
        return window

    def advance(self, sim: Simulation, deadline: float = math.inf) -> WatchedWindow | None:
        """
        Start a window when one is due, step the one under way; return it once it is done.

        ``deadline``: monotonic time at which to hand back (the window goes on at the next call).
        """
        if self._shadow is None:
            cause = self._due(sim)
            if cause is None:
                return None
            make = self.reference.reference
            self._shadow = Shadows(sim, self._kept(sim, lambda: (
                [sim.with_dt(sim.dt)] + ([make()] if make is not None else [])
                + [sim.with_dt(sim.dt)])), self.reference, cause)
        elif self.sentinel is not None:     # the states the window under way measures
            self.sentinel.outgrown(sim, self._measured(sim))
        if not self._shadow.advance(deadline):
            return None
        window, self._shadow = self._shadow.result, None
        return self._finished(window)

    def _step_beside(self, sim: Simulation, starts: bool = True) -> WatchedWindow | None:
        """
        Watch by a twin stepped beside ``sim`` itself, seen after each of its steps.

        A window starts when one is due (``starts``); one whose run was rebuilt is dropped (the
        next starts an interval after where it started), and one whose run was reset too (it
        is watched again as from a start).
        """
        if self._beside is not None and not self._beside.follows(sim):
            if sim.time < self._beside.start_s:
                self._next = None
            self._beside = None
        if self._beside is None:
            if not (starts and self._due(sim) is not None):
                return None
            ref = self.reference
            twin = self._kept(sim, lambda: [sim.with_dt(sim.dt)])[0]
            self._beside = TwinBeside(sim, ref.sample_s,
                                      twin_samples(ref.sample_s, ref.samples), twin)
        if not self._beside.observe(sim):
            return None
        return self._end_beside()

    def _end_beside(self) -> WatchedWindow:
        beside, self._beside = self._beside, None
        ref = self.reference
        span = ref.window_s if beside.done else beside.span_s
        return self._finished(WatchedWindow(beside.start_s, span, math.nan, ref.tolerance, '',
                                            beside.growth.rate()))

    def after_run(self, sim: Simulation) -> WatchedWindow | None:
        """
        End the window of a twin stepped beside ``sim`` with its run (None: none under way).

        Its last sample is the run's last step: a window that started one window before the
        run's end ends there, with the samples it took (``TWIN_MIN_SAMPLES`` at least).
        """
        if self._beside is None:
            return None
        window = self._step_beside(sim, starts=False)
        if window is not None or self._beside is None:
            return window
        if self._beside.growth.samples < TWIN_MIN_SAMPLES:
            self._beside = None
            return None
        return self._end_beside()

    def after_fallback(self, fallback: Simulation) -> 'RunWatch | None':
        """
        Return the watch of ``fallback``, the run this one's window fell back to (None: none).

        A full run is watched by its twin alone (:func:`twin_watched`), over what is left of the
        run, at the interval asked for (or the default); the richer plan is not watched again.
        Kept as :attr:`then`.
        """
        if not twin_watched(fallback, self.reference.tolerance):
            return None
        left = (None if self.run_s is None or self._began is None
                else self._began + self.run_s - fallback.time)
        self.then = watch_of(fallback, self.asked_s, run_s=left)
        return self.then

    def took_input(self, sim: Simulation) -> None:
        """
        Say that ``sim`` took an input no window measured (a user's pull, a wrench, a contact).

        A plan's watch starts a window from the run's state as soon as none is under way and
        its budget affords one (:attr:`least_s` after the last one's start; the span measured
        ends now): a local load can take a plan off its promise with little motion (a corner
        pulled aside by 5 N). A stream of inputs is watched no more often than the budget allows.
        """
        if self.sentinel is not None:
            self._measured_until = min(self._measured_until, sim.time)
            self._input = True

    def restart(self) -> None:
        """
        Drop the window under way and watch again as from a start (a reset, a band change).

        The plan's copy is made again from the run's state then.
        """
        self._shadow = self._beside = self._runs = self._next = None
        self._input, self._heading, self._started = False, False, -math.inf
        if self.sentinel is not None:
            self.sentinel.restart()

    def before_step(self, sim: Simulation, sample_s: float | None = None
                    ) -> tuple[Simulation, WatchedWindow | None]:
        """
        Advance the watch all the way before a step of ``sim`` (a run that is not streamed).

        Return the run that goes on (the fallback, from ``sim``'s state, where a window was
        beyond the tolerance: see :meth:`fallback`) and the window finished, or None. A run
        watched by its twin alone has it stepped beside the run (:meth:`after_run` ends the
        window that ends with the run).
        """
        if self.reference.reference is None:
            return sim, self._step_beside(sim)
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
            window = self.reference.window_s
            if self.run_s is not None and self.first_s >= self.run_s:     # none in the run
                return 'no window: ' + (
                    f'a window of its twin within {TWIN_SHARE:.0%} of the run would be shorter '
                    f'than {SHORTEST_TWIN_S:g} s' if not self.at_least_once else
                    f'the run is no longer than one {window:.3g} s window')
            against = (f'against {self.reference.against}' if self.reference.against
                       else 'of its twin moved by a hair')
            return (f'every {self.interval_s:.3g} s of the run: a {window:.3g} s window '
                    f'{against} (none yet)')
        worst = f'; largest {self.worst.describe()}' if self.worst not in (None, self.last) else ''
        amplified = (f'; amplifying first {self.amplifying.describe()}'
                     if self.amplifying not in (None, self.last) else '')
        count = f"{self.windows} window{'s' if self.windows > 1 else ''}"
        if self.sentinel is not None and self.sentinel.started:
            count += f' ({self.sentinel.started} started as the motion outgrew the measured)'
        return f'{count}: last {self.last.describe()}{worst}{amplified}'

"""
What a run is watched against, and what one watched window measured.

:class:`WatchReference` is what the pilot hands the watch (the reference run, the fallback, the
sample grid, the tolerance and the runs' modelled work); :class:`WatchedWindow` is the plan's
error from one state of the run on, with how fast a hair's difference grew there
(:mod:`~modal_spring_ros.core.auto.watch.amplification`).
"""
from __future__ import annotations

import dataclasses
import math
from typing import Callable, Mapping

from modal_spring_ros.core.auto.measured_error import PROMISE_WINDOW_S, WINDOW_ALLOWANCE
from modal_spring_ros.core.auto.watch.amplification import amplifies, describe_rate, UNBOUNDED
from modal_spring_ros.core.simulations import Simulation


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
    (:mod:`~.amplification`). ``against`` empty: a window of the twin alone (no error measured).
    ``cause``: why it started before it was due (:mod:`~.sentinel`; empty: it was due).
    ``worst``: the error over its worst quarter second (the promise allows ``WINDOW_ALLOWANCE``
    times the tolerance there: an error averaged over the window hides one that grows);
    ``heading``: the error its quarter seconds' trend reaches one window on (beyond the
    tolerance: the error is on its way up, and the next window follows at once).
    """

    start_s: float
    window_s: float
    error: float            # relative L2; inf: the plan diverged; nan: the reference did
    tolerance: float
    against: str
    growth: float = math.nan
    cause: str = ''
    worst: float = math.nan
    heading: float = math.nan

    @property
    def measured(self) -> bool:
        return not math.isnan(self.error)

    @property
    def amplifying(self) -> bool:
        """Tell whether the motion amplified its differences here: its error is not bounded."""
        return amplifies(self.growth)

    @property
    def rising(self) -> bool:
        """Tell whether a window within the promise is heading beyond the tolerance."""
        return self.within and self.heading > self.tolerance

    @property
    def within(self) -> bool:
        """Tell whether the plan met its tolerance (unmeasured and twin-only windows have)."""
        return not self.against or not self.measured or (
            self.error <= self.tolerance and not self.worst > WINDOW_ALLOWANCE * self.tolerance)

    def describe(self) -> str:
        span = f'over {self.window_s:.3g} s from t = {self.start_s:.4g} s' + (
            f' (started early: {self.cause})' if self.cause else '')
        amplified = f': {UNBOUNDED}' if self.amplifying else ''
        if not self.against:
            return f'{describe_rate(self.growth)} {span}{amplified}'
        span = f'{span} against {self.against}'
        amplified = f'; {describe_rate(self.growth)}{amplified}' if self.amplifying else ''
        if not self.measured:
            return f'not measured {span}: the reference diverged{amplified}'
        if math.isinf(self.error):
            return f'the plan diverged {span}{amplified}'
        worst = (f', {self.worst:.2%} over its worst {PROMISE_WINDOW_S:g} s'
                 if self.worst > WINDOW_ALLOWANCE * self.tolerance else '')
        return f'{self.error:.2%} {span}{worst}{amplified}'

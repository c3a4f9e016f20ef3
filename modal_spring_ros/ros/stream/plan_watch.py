"""
The node's watch over an automatic plan, stepped in the simulation thread's idle time.

:mod:`~modal_spring_ros.core.auto.watch.run_watch` measures a plan's error again from the run's own
state. The node steps its shadow runs between two frames, on the simulation thread (they share
the run's model and basis, and no other thread steps), until the next frame is due, so a frame
is never late for them. A window beyond the tolerance is handed to ``on_beyond``: the node falls
back by setting its own parameters (so that they, the parameter events and a capture say what
runs), and ``/diagnostics`` says so with a WARN for ``BEYOND_REPORT_S``. A window where the
motion amplified its differences (its error is not bounded, whatever runs) is a WARN as long,
and the run goes on.

A run is watched while it is the automatic plan the pilot measured: a band changed by hand on it
is no longer that plan (it is not watched again until a new plan is made), a reset or a
recovery restarts the watch, a new simulation brings its own (or none). The full run a fallback
sets is watched by its twin alone (:func:`~modal_spring_ros.core.auto.watch.twin_watch.
twin_watched`).
"""
from __future__ import annotations

import threading
import time
from typing import Callable, Mapping

from modal_spring_ros.core.auto.watch.run_watch import RunWatch, watch_of, WatchedWindow
from modal_spring_ros.core.auto.watch.twin_watch import twin_watched
from modal_spring_ros.core.simulations import Simulation
from modal_spring_ros.ros.parameters import CONFIG_NAMES
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter

#: What the node does when a watched window is beyond the tolerance: ``(window, settings)``, the
#: configuration fields that rebuild what the run falls back to.
FallBack = Callable[[WatchedWindow, Mapping[str, object]], None]
#: How long ``/diagnostics`` reports a window beyond the tolerance as a WARN, s.
BEYOND_REPORT_S = 30.0
#: Shortest slice a run stepped as fast as it can (no idle time) gives its watch per frame, s.
MIN_SLICE_S = 0.002
#: Share of one core the watch's shadows may take (modelled), at a real-time factor of 1: a
#: streaming node's budget is the machine it shares, not its plan's own work.
CORE_SHARE = 0.25


def beyond_message(window: WatchedWindow, settings: Mapping[str, object]) -> str:
    """Say that ``window`` was beyond the tolerance and what the run falls back to."""
    what = ('the full run' if settings.get('method') == 'full'
            else 'the whole band on a richer basis')
    return (f'automatic plan beyond its tolerance {window.tolerance:.2%}: '
            f'{window.describe()}; falling back to {what}')


def fall_back(node: Node, window: WatchedWindow, settings: Mapping[str, object],
              running: Callable[[], bool]) -> None:
    """
    Set ``node``'s parameters to the automatic plan's fallback (the watch found it beyond).

    From a thread of its own, atomically (``modal.auto`` off and ``method`` full go together):
    the parameters, ``/parameter_events`` and a capture say what runs from now. A refusal is
    logged unless the node is no longer ``running``.
    """
    values = {CONFIG_NAMES[name]: 0.0 if value is None else value
              for name, value in settings.items()}
    node.get_logger().warning(f'{beyond_message(window, settings)}: setting '
                              + ', '.join(f'{k}={v!r}' for k, v in values.items()))
    threading.Thread(target=_set_fallback, args=(node, values, running), daemon=True,
                     name='modal_spring_fallback').start()


def _set_fallback(node: Node, values: dict, running: Callable[[], bool]) -> None:
    try:
        result = node.set_parameters_atomically(
            [Parameter(name, value=value) for name, value in values.items()])
    except Exception as exc:  # shutting down, or a parameter refused by its type
        result = SetParametersResult(successful=False, reason=repr(exc))
    if not result.successful and running():
        node.get_logger().error(f'the fallback of the automatic plan was refused: '
                                f'{result.reason}')


class PlanWatch:
    """Watches the simulation thread's running plan; ``on_beyond(window, settings)`` falls back."""

    def __init__(self, on_beyond: FallBack):
        self._on_beyond = on_beyond
        self._watch: RunWatch | None = None
        self._sim: Simulation | None = None       # the run the watch is for
        self._interval = 0.0
        self._unwatched: Simulation | None = None  # a run whose band was changed by hand
        self._beyond = ('', -float('inf'))         # (message, monotonic time)
        self._fell: float | None = None            # the tolerance of a fallback under way

    def step(self, sim: Simulation, interval_s: float, deadline: float) -> None:
        """Step the watch of ``sim`` until ``deadline`` (monotonic), or do nothing."""
        watch = self._watch_for(sim, interval_s)
        if watch is None:
            return
        try:
            window = watch.advance(sim, max(deadline, time.monotonic() + MIN_SLICE_S))
        except Exception as exc:    # the watch is a check: its failure never costs the run
            self._unwatched, self._watch = sim, None
            self._beyond = (f'the automatic plan is no longer watched: {exc!r}',
                            time.monotonic())
            return
        if window is None:
            return
        if window.amplifying:          # reported, not fallen back: no other run would hold it
            self._beyond = (f'automatic plan: watched {window.describe()}', time.monotonic())
        if window.within:
            return
        settings = dict(sim.watch_reference.fallback_settings)
        self._beyond = (beyond_message(window, settings), time.monotonic())
        self._unwatched = sim                      # once: the fallback replaces it
        self._watch = None
        self._fell = window.tolerance if settings.get('method') == 'full' else None
        self._on_beyond(window, settings)

    def took_input(self, sim: Simulation) -> None:
        """Tell the watch of ``sim`` that it took an input (see :meth:`RunWatch.took_input`)."""
        if self._watch is not None and sim is self._sim:
            self._watch.took_input(sim)

    def restart(self) -> None:
        """Watch again an interval on (the run went back to rest, or was recovered)."""
        if self._watch is not None:
            self._watch.restart()

    def band_changed(self, sim: Simulation) -> None:
        """Stop watching ``sim``: with a band set by hand it is not the plan its pilot measured."""
        self._unwatched = sim
        self._watch = None

    def report(self) -> dict:
        """Return what the stream report on ``/diagnostics`` says of the watch."""
        message, when = self._beyond
        recent = message if time.monotonic() - when <= BEYOND_REPORT_S else ''
        watched = (self._watch.describe() if self._watch is not None
                   else message or 'off')
        return {'watched': watched, 'watch_beyond': recent}

    def _watch_for(self, sim: Simulation, interval_s: float) -> RunWatch | None:
        """Return the watch of ``sim`` (made for a new run or interval), or None: not watched."""
        if sim is self._unwatched:
            self._watch = None
        elif self._watch is None or self._sim is not sim or self._interval != interval_s:
            if self._fell is not None and self._sim is not sim:      # the fallback's full run
                twin_watched(sim, self._fell)
                self._fell = None
            self._watch = watch_of(sim, interval_s, budget=CORE_SHARE * 1e6)
            self._sim, self._interval = sim, interval_s
        return self._watch

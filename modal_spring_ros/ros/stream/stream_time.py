"""
The time the node publishes: simulation time that never goes back.

A run's simulation time starts again at 0 on ``~/reset`` and when a divergence sends the run back
to rest. Published as it is, that sends ``/clock`` and the stamps of the points and TF backwards:
nodes on ``use_sim_time`` see a jump back in time (tf2 buffers clear, RViz resets its displays)
and a tf2 buffer on any clock drops the object's frames as old data until they catch up.

:class:`StreamTime` publishes ``offset + t`` instead: when the simulation time ``t`` goes back,
the offset moves on by the time reached and one step, so the published time goes on from where
it was (the rest state, published at ``t`` = 0, one step after the last frame: no two frames
share a stamp, which a tf2 buffer would refuse as repeated data). The
offset is reported (the node's ``clock.offset_s``, on ``/parameter_events``), so a recording maps
its stamps back to simulation time (``modal_spring_replay --resimulate``).

Which clock stamps the frames is the ``stamp`` parameter (:func:`stamps_in_simulation_time`):
by default (``auto``) the node stamps as ROS nodes do, with its own clock (system time, or
``/clock``'s under ``use_sim_time``), and with simulation time only when it publishes that
time on ``/clock`` itself; each frame's simulation time is on ``sim_time`` either way.
"""
from __future__ import annotations

import threading
from typing import Callable


class StreamTime:
    """Published time ``offset + t``; the offset moves on when simulation time ``t`` goes back."""

    def __init__(self, offset: float = 0.0,
                 moved: Callable[[float], None] | None = None):
        """Start at ``offset`` (a node configured again goes on from its last time)."""
        self._offset = float(offset)
        self._last = 0.0
        self._moved = moved
        self._lock = threading.Lock()

    @property
    def offset(self) -> float:
        """Return the published time at which the current run's simulation time is 0, s."""
        return self._offset

    @property
    def reached(self) -> float:
        """Return the latest time published (or passed), s."""
        return self._offset + self._last

    def at(self, t: float, step: float = 0.0) -> float:
        """
        Return the published time of simulation time ``t``, s.

        When ``t`` went back, the offset moves on by the time reached and ``step`` (the run's time
        step) first, and ``moved(offset)`` is called.
        """
        with self._lock:
            moved = t < self._last
            if moved:
                self._offset += self._last + step
            self._last = t
            offset = self._offset
        if moved and self._moved is not None:
            self._moved(offset)
        return offset + t


def stamps_in_simulation_time(values: dict) -> bool:
    """Return whether frames are stamped with published simulation time (else the node's clock)."""
    return values['stamp'] == 'sim' or (values['stamp'] == 'auto' and values['publish_clock'])


def clock_warnings(use_sim_time: bool, values: dict) -> list[str]:
    """Return what a node's time settings get wrong together (``values``: its parameters)."""
    if use_sim_time and values['stamp'] == 'sim' and not values['publish_clock']:
        return ["use_sim_time is true: this node's clock follows another /clock, but its stamps "
                'are its own simulation time (stamp sim, publish_clock false); stamp:=wall '
                "stamps with /clock's time, publish_clock:=true makes this node the clock"]
    return []

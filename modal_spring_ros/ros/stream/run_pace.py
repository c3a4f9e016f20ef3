"""
The pace a run keeps: the simulation time it owes by the clock it follows.

A run with real-time factor ``r`` owes ``r`` simulated seconds per second of its pace clock since
an anchor (a pace-clock time and the simulation time then). The pace clock is the wall clock, or,
for a node that follows another node's ``/clock`` (``use_sim_time``, not publishing ``/clock``
itself), that clock (:func:`pace_reading`): a simulator under ``use_sim_time`` advances as the
clock does, slows with a bag played slowly and pauses with a paused one.

A clock that goes back (a bag played in a loop), one that starts (a first ``/clock`` after none,
ROS time 0 until then) or a change of clock (``use_sim_time`` set at run time) would leave the
run owing, or ahead by, the jump: the anchor is then set afresh where the run is.
"""
from __future__ import annotations

import time
from typing import Callable

#: a pace clock's reading: (its name, seconds); 'wall' is the wall clock
Reading = tuple[str, float]


def wall_pace() -> Reading:
    """Return the wall clock as a pace clock: ('wall', monotonic seconds)."""
    return 'wall', time.monotonic()


def pace_reading(clock, publish_clock: bool) -> Reading:
    """
    Return the reading of the clock a node's run keeps pace with.

    The node's ROS ``clock`` when it follows another node's ``/clock`` (``use_sim_time``, and not
    publishing ``/clock`` itself: its own clock would wait on its own steps); else the wall's.
    """
    if clock.ros_time_is_active and not publish_clock:
        return 'ros', clock.now().nanoseconds * 1e-9
    return wall_pace()


class RunPace:
    """The simulation time a run owes by its pace clock (see the module text)."""

    def __init__(self, clock: Callable[[], Reading] = wall_pace, sim_time: float = 0.0):
        """Keep pace with ``clock`` from now, where the run is at ``sim_time``."""
        self._clock = clock
        self._source, now = clock()
        self._anchor = (now, sim_time)
        self._last = now

    def read(self) -> Reading:
        """Return the pace clock's reading now."""
        return self._clock()

    def owed(self, sim_time: float, rtf: float) -> tuple[float, bool]:
        """
        Return the simulation time owed now at ``rtf``, and whether the clock jumped.

        After a jump the anchor is ``sim_time`` now (nothing owed, nothing ahead).
        """
        source, now = self._clock()
        jumped = (source != self._source or now < self._anchor[0]
                  or self._anchor[0] == 0.0 < now)
        if jumped:
            self._source, self._anchor = source, (now, sim_time)
        self._last = now
        return self._anchor[1] + (now - self._anchor[0]) * rtf, jumped

    def anchor(self, sim_time: float, at_last_reading: bool = False) -> None:
        """Owe from ``sim_time`` now (or at the last reading :meth:`owed` took)."""
        self._anchor = (self._last if at_last_reading else self._clock()[1], sim_time)

    def since(self, start: Reading) -> tuple[float, bool]:
        """
        Return the pace clock's advance since ``start`` and whether it stood still.

        A clock other than the wall's may stand still (a paused bag); a change of clock since
        ``start`` counts as no advance.
        """
        source, now = self._clock()
        span = now - start[1] if source == start[0] else 0.0
        return span, source != 'wall' and span <= 0.0

"""Simulation seconds <-> ``builtin_interfaces/Time`` (exact to the nanosecond)."""
from __future__ import annotations

import math

try:     # making a stamp needs ROS's message class; reading one does not
    from builtin_interfaces.msg import Time
except ImportError:
    Time = None


def to_time_msg(seconds: float) -> Time:
    sec = int(math.floor(seconds))
    nanosec = int(round((seconds - sec) * 1e9))
    if nanosec >= 1_000_000_000:
        sec, nanosec = sec + 1, nanosec - 1_000_000_000
    return Time(sec=sec, nanosec=nanosec)


def to_nanoseconds(stamp: Time) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def to_seconds(stamp: Time) -> float:
    return stamp.sec + 1e-9 * stamp.nanosec

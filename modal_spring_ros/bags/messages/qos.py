"""
QoS profiles as rosbag2 (metadata version 9) writes them: a YAML list in a string.

Each profile: ``history``, ``depth``, ``reliability``, ``durability``, ``deadline``,
``lifespan``, ``liveliness``, ``liveliness_lease_duration`` and
``avoid_ros_namespace_conventions``; policies by name (``keep_last``, ``reliable``, ...) since
version 9, as integers before; durations as ``{sec, nsec}``.
"""
from __future__ import annotations

from rclpy.duration import Duration
from rclpy.qos import (DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile,
                       ReliabilityPolicy)
import yaml

_POLICIES = {'history': HistoryPolicy, 'reliability': ReliabilityPolicy,
             'durability': DurabilityPolicy, 'liveliness': LivelinessPolicy}
_DURATIONS = ('deadline', 'lifespan', 'liveliness_lease_duration')


def _duration(d: Duration) -> dict:
    ns = d.nanoseconds
    return {'sec': ns // 1_000_000_000, 'nsec': ns % 1_000_000_000}


def profile_to_dict(p: QoSProfile) -> dict:
    return {
        'history': p.history.name.lower(),
        'depth': int(p.depth),
        'reliability': p.reliability.name.lower(),
        'durability': p.durability.name.lower(),
        'deadline': _duration(p.deadline),
        'lifespan': _duration(p.lifespan),
        'liveliness': p.liveliness.name.lower(),
        'liveliness_lease_duration': _duration(p.liveliness_lease_duration),
        'avoid_ros_namespace_conventions': bool(p.avoid_ros_namespace_conventions),
    }


def profiles_to_yaml(profiles: list[QoSProfile]) -> str:
    """Return the ``offered_qos_profiles`` string (empty list -> empty string, as rosbag2)."""
    if not profiles:
        return ''
    return yaml.safe_dump([profile_to_dict(p) for p in profiles], sort_keys=False).rstrip('\n')


def profiles_from_yaml(text: str) -> list[QoSProfile]:
    """Parse an ``offered_qos_profiles`` string of any metadata version."""
    if not text:
        return []
    out = []
    for item in yaml.safe_load(text) or []:
        kwargs = {'depth': int(item.get('depth', 10)) or 10}
        for key, enum in _POLICIES.items():
            value = item.get(key)
            if value is None:
                continue
            kwargs[key] = enum(value) if isinstance(value, int) else enum[str(value).upper()]
        for key in _DURATIONS:
            if key in item:
                d = item[key]
                kwargs[key] = Duration(seconds=int(d['sec']), nanoseconds=int(d['nsec']))
        kwargs['avoid_ros_namespace_conventions'] = bool(
            item.get('avoid_ros_namespace_conventions', False))
        out.append(QoSProfile(**kwargs))
    return out


def playback_profile(profiles: list[QoSProfile]) -> QoSProfile:
    """
    Return what a player offers.

    The recorded offer when all publishers agreed, else the default (reliable, volatile, keep last
    10), as rosbag2 does.
    """
    if not profiles:
        return QoSProfile(depth=10)
    first = profiles[0]
    same = all(p.reliability == first.reliability and p.durability == first.durability
               for p in profiles)
    if not same:
        return QoSProfile(depth=10)
    return QoSProfile(depth=max(first.depth, 10), reliability=first.reliability,
                      durability=first.durability)

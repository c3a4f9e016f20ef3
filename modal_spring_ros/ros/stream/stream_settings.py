"""The node's stream settings: what the simulation thread reads from the parameters every frame."""
from __future__ import annotations

import dataclasses

from modal_spring_ros.core.config import DEFAULT_WATCH_S


@dataclasses.dataclass(frozen=True)
class StreamSettings:
    """The node's stream settings, read by the thread on every frame."""

    publish_rate_hz: float = 60.0
    mesh_rate_hz: float = 10.0
    realtime_factor: float = 1.0
    strain_warning: float = 0.1
    watch_s: float = DEFAULT_WATCH_S   # an automatic plan's watch interval, s (0: not watched)

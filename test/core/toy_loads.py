"""
A load that lives outside the package: a steady wind, the same force on every free particle.

It knows nothing of the package but the load contract; the test that uses it sets it on runs
by its name alone.
"""
from __future__ import annotations

import dataclasses
import math
from typing import ClassVar

from modal_spring_ros.core.loads.base import Load
import numpy as np


@dataclasses.dataclass(frozen=True)
class Wind(Load):
    """``force`` (d,) N on every free particle, in world directions, until ``until``."""

    name: ClassVar[str] = 'wind'
    force: np.ndarray
    until: float = math.inf

    def world_forces(self, model, world_positions, t):
        count = model.free_particles.size
        return np.arange(count * model.dimension), np.tile(self.force, count)

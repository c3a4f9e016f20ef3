"""The operators of uncoupled equations (``M``, ``C``, ``K`` diagonal): the modal equations."""
from __future__ import annotations

import numpy as np


class DiagonalOperators:
    """:class:`~modal_spring_ros.core.integrators.base.Operators` of diagonal ``M, C, K``."""

    def __init__(self, mass: np.ndarray | float, damping: np.ndarray | float,
                 stiffness: np.ndarray, dt: float, acceleration_floor: float = 0.0):
        self.mass = mass
        self.acceleration_floor = acceleration_floor
        self.damping = damping
        self.stiffness = stiffness
        self._inv_explicit = 1.0 / (mass + 0.5 * dt * damping)
        self._inv_average = 1.0 / (mass + 0.5 * dt * damping + 0.25 * dt * dt * stiffness)
        self._has_damping = np.any(np.asarray(damping) != 0.0)

    def damp(self, v):
        return self.damping * v if self._has_damping else 0.0

    def stiff(self, u):
        return self.stiffness * u

    def explicit_acceleration(self, force, v_pred):
        if self._has_damping:
            force = force - self.damping * v_pred
        return self._inv_explicit * force

    def solve_average(self, rhs):
        return self._inv_average * rhs

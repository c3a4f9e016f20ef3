"""
The explicit Newmark step (beta = 0, gamma = 1/2): the paper's eqs. 17-19.

Stable for ``dt < 2 / omega_max`` of the coordinates stepped; one force evaluation a step.
"""
from __future__ import annotations

import math

from modal_spring_ros.core.integrators.base import Force, Integrator, Operators, StepResult
import numpy as np


class ExplicitNewmark(Integrator):
    name = 'explicit'

    @classmethod
    def stable_step(cls, omega_max: float) -> float:
        """Return ``2 / omega_max`` (an undamped coordinate's limit)."""
        return math.inf if omega_max <= 0.0 else 2.0 / omega_max

    def step(self, u: np.ndarray, v: np.ndarray, a: np.ndarray, dt: float, force: Force,
             ops: Operators) -> StepResult:
        v_pred = v + (0.5 * dt) * a
        u1 = u + dt * v_pred  # = u + dt v + dt^2/2 a
        a1 = ops.explicit_acceleration(force(u1), v_pred)
        v1 = v_pred + (0.5 * dt) * a1
        return StepResult(u1, v1, a1, 1)

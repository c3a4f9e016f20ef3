"""
An integrator that lives outside the package: symplectic Euler, stable below ``2 / omega``.

It knows nothing of the package but the integrator contract, and owns its stability limit in
:meth:`stable_step`, stated here more cautiously (``1 / omega``) so that a test can tell that
the runs ask it, not a formula of their own.
"""
from __future__ import annotations

import math

from modal_spring_ros.core.integrators.base import Integrator, StepResult


class SymplecticEuler(Integrator):
    """``v += dt a(u)``, then ``u += dt v`` (one force evaluation a step)."""

    name = 'symplectic_euler'

    @classmethod
    def stable_step(cls, omega_max: float) -> float:
        return math.inf if omega_max <= 0.0 else 1.0 / omega_max

    def step(self, u, v, a, dt, force, ops):
        v1 = v + dt * a
        u1 = u + dt * v1
        a1 = ops.explicit_acceleration(force(u1), v1)
        return StepResult(u1, v1, a1, 1)

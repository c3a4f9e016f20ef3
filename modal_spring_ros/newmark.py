"""Newmark time stepping for ``M a + C v = F(u, t)``, in modal or physical coordinates.

Two members of the Newmark family (gamma = 1/2):

* ``explicit`` (beta = 0): the paper's eqs. 17-19. Stable for ``dt < 2 / omega_max``.
* ``average`` (beta = 1/4, average acceleration / trapezoidal rule): unconditionally stable
  for the linear part. The nonlinear spring force is handled by a modified Newton iteration
  with the rest stiffness ``K`` as the fixed tangent:
  ``(M + dt/2 C + dt^2/4 K) a1 = F(u1) + K u1 - C v_pred - K u_pred``, repeated until ``a1``
  stops changing. The first iterate evaluates the forces at the current displacement
  (``u1 = u``), so that it is the step linearised about a state the forces are known at;
  starting from the extrapolation ``u + dt v + dt^2/2 a`` instead puts the particles far off
  at large steps (strains of several hundred percent at 10 times the explicit limit), where
  the fixed tangent no longer converges. A step whose iteration does not converge is
  reported, not accepted.

The linear algebra is supplied by an :class:`Operators` object, so the same two functions step
the diagonal modal equations and the sparse physical ones.
"""
from __future__ import annotations

from typing import Callable, Protocol

import numpy as np

INTEGRATORS = ("explicit", "average")


class Operators(Protocol):
    """Linear parts of the equations of motion, for one time step ``dt``."""

    def damp(self, v: np.ndarray) -> np.ndarray | float:
        """``C v`` (may return 0.0 without damping)."""

    def stiff(self, u: np.ndarray) -> np.ndarray:
        """``K u`` with the rest stiffness."""

    def explicit_acceleration(self, force: np.ndarray, v_pred: np.ndarray) -> np.ndarray:
        """``(M + dt/2 C)^-1 (force - C v_pred)``: the explicit step's new acceleration."""

    def solve_average(self, rhs: np.ndarray) -> np.ndarray:
        """``(M + dt/2 C + dt^2/4 K)^-1 rhs``."""


class NonConvergence(RuntimeError):
    """The implicit step's iteration did not converge (strong nonlinearity for this step)."""


def explicit_step(u: np.ndarray, v: np.ndarray, a: np.ndarray, dt: float,
                  force: Callable[[np.ndarray], np.ndarray], ops: Operators
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One explicit Newmark step (beta = 0, gamma = 1/2); returns ``u1, v1, a1``."""
    v_pred = v + (0.5 * dt) * a
    u1 = u + dt * v_pred  # = u + dt v + dt^2/2 a
    a1 = ops.explicit_acceleration(force(u1), v_pred)
    v1 = v_pred + (0.5 * dt) * a1
    return u1, v1, a1


def average_step(u: np.ndarray, v: np.ndarray, a: np.ndarray, dt: float,
                 force: Callable[[np.ndarray], np.ndarray], ops: Operators,
                 rtol: float = 1e-10, max_iterations: int = 25
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """One average-acceleration step; returns ``u1, v1, a1, iterations``.

    Raises:
        NonConvergence: the modified Newton iteration did not settle in ``max_iterations``.
    """
    h2 = 0.25 * dt * dt
    u_pred = u + dt * v + h2 * a
    v_pred = v + (0.5 * dt) * a
    base = -ops.damp(v_pred) - ops.stiff(u_pred)
    a1 = (u - u_pred) / h2  # first iterate at u1 = u: the forces where they are known to be sane
    for iteration in range(1, max_iterations + 1):
        u1 = u_pred + h2 * a1
        a_new = ops.solve_average(force(u1) + ops.stiff(u1) + base)
        change = float(np.max(np.abs(a_new - a1))) if a_new.size else 0.0
        size = float(np.max(np.abs(a_new))) if a_new.size else 0.0
        a1 = a_new
        if not np.isfinite(change):
            break
        if change <= rtol * max(size, 1e-300) or change == 0.0:
            return u_pred + h2 * a1, v_pred + (0.5 * dt) * a1, a1, iteration
    raise NonConvergence(
        f"average-acceleration iteration did not converge in {max_iterations} iterations "
        f"(dt = {dt:g} s is too large for this nonlinearity)")


class DiagonalOperators:
    """Operators of uncoupled equations: ``M``, ``C``, ``K`` are diagonal (vectors)."""

    def __init__(self, mass: np.ndarray | float, damping: np.ndarray | float,
                 stiffness: np.ndarray, dt: float):
        self.mass = mass
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

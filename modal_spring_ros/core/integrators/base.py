"""
The integrator contract: one Newmark step of ``M a + C v = F(u, t)`` in any coordinates.

An integrator advances ``(u, v, a)`` by ``dt`` given the nonlinear force ``F`` and the linear
algebra of the equations (an :class:`Operators`), so that the same integrator steps the
diagonal modal equations and the sparse physical ones.
"""
from __future__ import annotations

import abc
from typing import Callable, ClassVar, NamedTuple, Protocol

import numpy as np

Force = Callable[[np.ndarray], np.ndarray]
#: an acceleration floor's share of the gravity acceleration (see ``Operators``)
ROUNDOFF_SHARE = 1e-11


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

    #: accelerations below this are the forces' round-off (an iteration has converged there):
    #: a loaded shape is an equilibrium to round-off, not exactly
    acceleration_floor: float


class NonConvergence(RuntimeError):
    """The implicit step's iteration did not converge (strong nonlinearity for this step)."""


class StepResult(NamedTuple):
    """The state after one step, and how many force evaluations the step took."""

    u: np.ndarray
    v: np.ndarray
    a: np.ndarray
    iterations: int


class Integrator(abc.ABC):
    """
    One member of the Newmark family (gamma = 1/2). Stateless: one instance serves all.

    It owns its stability: :meth:`stable_step` is the only place its limit is written, and
    every check, step choice and report asks it.
    """

    #: registry name
    name: ClassVar[str]
    #: force evaluations a step is taken to make before any is counted (what the work model
    #: prices a run not yet stepped at)
    evaluations_per_step: ClassVar[float] = 1.0

    @classmethod
    @abc.abstractmethod
    def stable_step(cls, omega_max: float) -> float:
        """Return the largest stable step for coordinates up to ``omega_max`` rad/s (inf: any)."""

    @abc.abstractmethod
    def step(self, u: np.ndarray, v: np.ndarray, a: np.ndarray, dt: float, force: Force,
             ops: Operators) -> StepResult:
        """Advance one step; raises :class:`NonConvergence` when an iteration fails."""

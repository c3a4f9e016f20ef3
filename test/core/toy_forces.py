"""
A force model that lives outside the package: the linearised springs, ``Q = -omega^2 q + loads``.

It knows nothing of the package but the force model contract; the test that uses it adds it
through the registry alone (one entry in ``FORCES``).
"""
from __future__ import annotations

from modal_spring_ros.core.forces import ForceContext, ForceModel, ForceOptions, ForceReport
import numpy as np


class LinearForces(ForceModel):
    """The rest stiffness of the coordinates in place of the nonlinear springs (small motion)."""

    name = 'linear'

    @classmethod
    def build(cls, context: ForceContext, options: ForceOptions) -> 'LinearForces':
        return cls(context)

    def __init__(self, context: ForceContext):
        self.exact = context.exact
        self.omega2 = context.omega2
        self.calls = 0

    def __call__(self, q: np.ndarray, t: float) -> np.ndarray:
        self.calls += 1
        return self.exact.loads(t) - self.omega2 * q

    def loads(self, t: float) -> np.ndarray:
        return self.exact.loads(t)

    def gravity(self) -> np.ndarray:
        return self.exact.gravity()

    @property
    def evaluated_share(self) -> float:
        return 0.0  # no spring is ever evaluated

    def report(self) -> ForceReport:
        return ForceReport(self.name, f'linear springs ({self.calls} calls)', 0)

"""
A spring law that lives outside the package: stiffer in tension, ``f = k e (1 + e / l)``.

``e = L - l``: ``f' = k (1 + 2 e / l)``, ``f'' = 2 k / l`` (non-zero at rest, so that the modal
derivatives' curvature term is exercised) and ``W = k e^2 / 2 + k e^3 / (3 l)``. It knows
nothing of the package but the law contract.
"""
from __future__ import annotations

from modal_spring_ros.core.laws import SpringLaw
import numpy as np


class StiffeningSpring(SpringLaw):
    """A spring whose stiffness grows with its stretch."""

    name = 'stiffening'

    def tension(self, length):
        e = length - self.rest_length
        return self.stiffness * e * (1.0 + e * self.inv_l)

    def tension_slope(self, length):
        e = length - self.rest_length
        return self.stiffness * (1.0 + 2.0 * e * self.inv_l)

    def tension_curvature(self, length):
        return np.broadcast_to(2.0 * self.stiffness * self.inv_l, np.shape(length)).copy()

    def energy(self, length):
        e = length - self.rest_length
        return self.stiffness * e * e * (0.5 + e * self.inv_l / 3.0)

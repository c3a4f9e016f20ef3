"""
The linear spring (the paper's, eq. 20): ``f(L) = k (L - l)``, ``W = k (L - l)^2 / 2``.

Its per-step pull ``f / L = k - k l / L`` runs in place over the lengths (two array operations,
no temporary): the hot path of every force evaluation.
"""
from __future__ import annotations

from modal_spring_ros.core.laws.base import SpringLaw
import numpy as np


class LinearSpring(SpringLaw):
    """Hooke's spring along its axis."""

    name = 'linear'

    def __init__(self, stiffness: np.ndarray, rest_length: np.ndarray):
        super().__init__(stiffness, rest_length)
        self._kl = self.stiffness * self.rest_length

    def tension(self, length: np.ndarray) -> np.ndarray:
        return self.stiffness * (length - self.rest_length)

    def tension_slope(self, length: np.ndarray) -> np.ndarray:
        return np.broadcast_to(self.stiffness, np.shape(length)).copy()

    def tension_curvature(self, length: np.ndarray) -> np.ndarray:
        return np.zeros(np.shape(length))

    def energy(self, length: np.ndarray) -> np.ndarray:
        return 0.5 * self.stiffness * (length - self.rest_length) ** 2

    def pull_per_length(self, length: np.ndarray) -> np.ndarray:
        np.divide(self._kl, length, out=length)
        return np.subtract(self.stiffness, length, out=length)

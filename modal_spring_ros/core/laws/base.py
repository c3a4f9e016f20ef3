"""
The spring-law contract: a spring's pull as a function of its length, and what follows from it.

A law gives, per spring of stiffness ``k`` and rest length ``l``, the tension ``f(L)`` along
the spring at length ``L`` (positive stretched, ``f(l) = 0``), its first and second derivatives
``f'(L)`` and ``f''(L)``, and the stored energy ``W(L)`` (``W' = f``, ``W(l) = 0``). Everything
the engine needs is derived here once, for every law:

* the force on particle ``i`` is ``(f / L) (x_j - x_i)`` (paper eq. 20 for the linear law),
* the tangent stiffness block is ``a I + b n n^T`` with ``a = f / L``, ``b = f' - f / L``,
* the rest stiffness is ``f'(l)`` along the spring (paper eq. 6),
* the tangent's derivative along a displacement (modal derivatives) uses ``f''`` and ``b / L``.

A law is bound to its springs' arrays (``k``, ``l``) when built; :meth:`SpringLaw.subset` binds
the same law to some of them (a spring sample). Laws are listed by name in
:data:`modal_spring_ros.core.laws.SPRING_LAWS`; a scene names its law (``spring_law``).
"""
from __future__ import annotations

import abc
from typing import ClassVar

import numpy as np


class SpringLaw(abc.ABC):
    """One spring law bound to (E,) stiffnesses ``k`` (N/m) and rest lengths ``l`` (m)."""

    #: registry name (the scene file's ``springs.law``)
    name: ClassVar[str]

    def __init__(self, stiffness: np.ndarray, rest_length: np.ndarray):
        self.stiffness = np.asarray(stiffness, dtype=float)
        self.rest_length = np.asarray(rest_length, dtype=float)
        self.inv_l = 1.0 / self.rest_length

    def subset(self, springs: np.ndarray) -> 'SpringLaw':
        """Return the same law bound to the springs ``springs`` only."""
        return type(self)(self.stiffness[springs], self.rest_length[springs])

    # -- the law itself ---------------------------------------------------------------------
    @abc.abstractmethod
    def tension(self, length: np.ndarray) -> np.ndarray:
        """Return ``f(L)``, each spring's pull along itself at lengths ``length`` (..., E), N."""

    @abc.abstractmethod
    def tension_slope(self, length: np.ndarray) -> np.ndarray:
        """Return ``f'(L)``, N/m."""

    @abc.abstractmethod
    def tension_curvature(self, length: np.ndarray) -> np.ndarray:
        """Return ``f''(L)``, N/m^2."""

    @abc.abstractmethod
    def energy(self, length: np.ndarray) -> np.ndarray:
        """Return each spring's stored energy ``W`` at ``length`` (J), zero at its rest length."""

    # -- derived, the same for every law ----------------------------------------------------
    def pull_per_length(self, length: np.ndarray) -> np.ndarray:
        """
        Return ``f(L) / L``, in place over ``length`` where a law can (the per-step hot path).

        The spring vector ``x_j - x_i`` times it is the force on ``i``.
        """
        return np.divide(self.tension(length), length, out=length)

    def tangent(self, length: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return ``(a, b)`` of each spring's tangent block ``a I + b n n^T`` at ``length``."""
        a = self.tension(length) / length
        return a, self.tension_slope(length) - a

    def rest_stiffness(self) -> np.ndarray:
        """Return ``f'(l)``, each spring's stiffness along itself at rest (eq. 6's ``k``)."""
        return self.tension_slope(self.rest_length)

    def derivative_terms(self, length: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """
        Return ``(f'', b)`` at lengths ``length``: the tangent's change along a displacement.

        Along a change ``beta`` of the spring vector (``n' = (beta - n (n.beta)) / L``) the
        tangent applied to ``alpha`` changes by
        ``f'' (n.beta)(n.alpha) n + (b / L)(n.beta)(alpha - n (n.alpha))
        + b (n' (n.alpha) + n (n'.alpha))``.
        """
        a = self.tension(length) / length
        return self.tension_curvature(length), self.tension_slope(length) - a

"""
Which basis a band needs: rest modes while the motion stays small, their derivatives beyond.

Rest modes miss the springs' second-order response. For a displacement ``u1`` of the kept
modes, that response is the static solution of the quadratic term of the spring forces,

    K0 u2 = -1/2 (dK/du along u1) u1,

and rest modes miss the part of ``u2`` outside their span. Missing it gives the motion the
wrong stiffness, so the error it causes grows with how strongly the drive resonates: a response
amplified ``A`` times by a drive near a kept mode carries a relative stiffness error ``e``
into an amplitude and phase error of about ``A e``. So the predicted error of a basis is

    A * ||u2 - P u2||_M / ||u1||_M

with ``P`` the mass projection on the basis (the kept rest modes, or those and the
coordinates the band adds), ``u1`` the kept modes' response to the scene's loads at their
amplitude (gravity statically, each drive term through the modes' damped frequency response)
and ``A`` the response-weighted amplification of the drive. Calibration: on
``sheet_10x10_resonance`` (a drive at the first resonance, ``A = 25``) it predicts 33 % for
rest modes where the full run measures 31.5 %; on ``sheet_10x10`` it predicts 0.01 % of
second-order error (the 1 % rest modes measure there is truncation, which the mode choice
predicts separately).

:func:`choose_basis` keeps rest modes when their prediction is within the budget (they are
cheaper: fewer coordinates and a step twice as long), else the derivatives basis when it
predicts less. Beyond small deformation the spring forces are also evaluated on every step
(the refreshed forces continue them along a tangent of the rest shape, which the motion has
left). One solve with the basis's kept factorisation (in the worker process on large
scenes); the derivatives are computed only when rest modes do not do, and then they are the
band's own, kept for the run.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Callable

from modal_spring_ros.core.bases.basis import ModalBasis
from modal_spring_ros.core.bases.derivatives import AddedCoordinates, tangent_derivative
from modal_spring_ros.core.model.model import MassSpringModel
import numpy as np


@dataclasses.dataclass(frozen=True)
class BasisChoice:
    """The basis chosen for a band, and the second-order error predicted for each basis."""

    kind: str                       # "rest" or "derivatives"
    predicted: dict[str, float]     # basis -> predicted error (derivatives: when computed)
    amplification: float           # of the drive's response
    small: bool                     # rest modes are within the budget: small deformation

    def describe(self) -> str:
        errors = ', '.join(f'{k} {v:.2%}' for k, v in self.predicted.items())
        return f'{self.kind} basis (predicted second-order error: {errors})'


def response(model: MassSpringModel, phi: np.ndarray, omega: np.ndarray
             ) -> tuple[np.ndarray, float]:
    """
    Amplitude of the kept modes' response to the scene's loads (in phase: an upper bound).

    And the response-weighted amplification of the drive (1 without one).
    """
    damping = model.scene.damping.modal_coefficients(omega)
    w2 = omega ** 2
    q = np.zeros(omega.size)
    if np.any(model.gravity_force):
        q += np.abs(phi.T @ model.gravity_force) / w2
    driven, weighted = np.zeros(omega.size), np.zeros(omega.size)
    for pattern, acceleration, frequency in _drives(model):
        drive = 2.0 * math.pi * frequency
        gain = 1.0 / np.sqrt((w2 - drive ** 2) ** 2 + (damping * drive) ** 2)
        amplitude = np.abs(phi.T @ pattern) * acceleration * gain
        driven += amplitude
        weighted += amplitude * w2 * gain
    q += driven
    amplification = float(weighted.sum() / driven.sum()) if driven.sum() > 0.0 else 1.0
    return q, max(amplification, 1.0)


def _drives(model: MassSpringModel):
    """
    Return each term of the clamp's motion as a load.

    Each is (load pattern per unit acceleration, acceleration amplitude, frequency): a shake's
    inertial load; a turn's Euler and centrifugal loads about its pivot and gravity turned
    through its angle.
    """
    d, mass = model.dimension, model.mass_dof
    motion = model.motion
    for c in motion.components:
        if c.amplitude != 0.0 and c.axis in model.axes:
            slot = model.axes.index(c.axis)
            pattern = np.zeros(model.n_free_dof)
            pattern[slot::d] = mass[slot::d]
            yield pattern, abs(c.amplitude) * (2.0 * math.pi * c.frequency_hz) ** 2, \
                c.frequency_hz
    g = float(np.linalg.norm(model.scene.gravity))
    rest = model.rest[model.free_particles]
    for c in motion.rotations:
        if c.amplitude == 0.0:
            continue
        angle, rate = abs(c.amplitude), 2.0 * math.pi * c.frequency_hz
        arm = rest - np.asarray(c.pivot)[model.axes]
        for i in range(d):
            for j in range(d):
                pattern = np.zeros(model.n_free_dof)
                pattern[i::d] = mass[i::d] * arm[:, j]
                yield pattern, angle * rate ** 2 + (angle * rate) ** 2, c.frequency_hz
            if g > 0.0:
                pattern = np.zeros(model.n_free_dof)
                pattern[i::d] = mass[i::d]
                yield pattern, g * math.sin(min(angle, math.pi / 2)), c.frequency_hz


def _second_order(solve, model: MassSpringModel, u1: np.ndarray) -> np.ndarray:
    """``u2 = -1/2 K0^-1 (dK/du along u1) u1``."""
    return -0.5 * solve(tangent_derivative(model, u1[:, None], u1[:, None]))[:, 0]


def choose_basis(model: MassSpringModel, basis: ModalBasis, keep: np.ndarray, budget: float,
                 added: Callable[[np.ndarray], AddedCoordinates]) -> BasisChoice:
    """
    Rest modes if their predicted second-order error is within ``budget``.

    Else the derivatives basis when it predicts less (``added(keep)``: what the band adds).
    """
    phi, omega = basis.vectors[:, keep], basis.omega[keep]
    mass = model.mass_dof
    q, amplification = response(model, phi, omega)
    u1 = phi @ q
    size = math.sqrt(float(u1 @ (mass * u1)))
    if size == 0.0:
        return BasisChoice('rest', {'rest': 0.0}, amplification, True)
    u2 = basis.call_with_solve(_second_order, model, u1)

    def missed(vectors: np.ndarray) -> float:
        rest = u2 - vectors @ (vectors.T @ (mass * u2))
        return amplification * math.sqrt(float(rest @ (mass * rest))) / size

    predicted = {'rest': missed(phi)}
    if predicted['rest'] <= budget:
        return BasisChoice('rest', predicted, amplification, True)
    predicted['derivatives'] = missed(np.column_stack([phi, added(keep).vectors]))
    kind = 'derivatives' if predicted['derivatives'] < predicted['rest'] else 'rest'
    return BasisChoice(kind, predicted, amplification, False)

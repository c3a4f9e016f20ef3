"""
A rigid motion of space and its time derivatives: where a moving clamp carries its body.

A point at rest at ``X`` is carried to ``x = R X + b``. With the velocity and acceleration of
both parts, this is what a floating frame of reference needs: the body's own deformation is
written in the frame (``y = R^T (x - b)``), and the frame's motion becomes the inertial loads
of :mod:`modal_spring_ros.core.motion.frame_loads`.
"""
from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np


def cross_matrix(axis: int) -> np.ndarray:
    """``[e_axis]x``: the matrix of ``v -> e_axis x v`` (3 x 3)."""
    out = np.zeros((3, 3))
    i, j = (axis + 1) % 3, (axis + 2) % 3
    out[j, i], out[i, j] = 1.0, -1.0
    return out


def axis_rotation(axis: int, angle: float) -> np.ndarray:
    """Rotation by ``angle`` (rad, right-handed) about world axis ``axis`` (3 x 3)."""
    out = np.eye(3)
    c, s = math.cos(angle), math.sin(angle)
    i, j = (axis + 1) % 3, (axis + 2) % 3
    out[i, i] = out[j, j] = c
    out[j, i], out[i, j] = s, -s
    return out


@dataclasses.dataclass(frozen=True)
class RigidFrame:
    """
    ``x = R X + b`` at one instant, with the first and second time derivatives of both.

    Arrays are 3 x 3 (``rotation`` and its rates) and (3,) (``translation`` and its rates).
    """

    rotation: np.ndarray
    rotation_rate: np.ndarray
    rotation_acceleration: np.ndarray
    translation: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray

    @classmethod
    def identity(cls) -> 'RigidFrame':
        zero = np.zeros((3, 3))
        return cls(np.eye(3), zero, zero, np.zeros(3), np.zeros(3), np.zeros(3))

    @classmethod
    def turn(cls, rotation: np.ndarray, rate: np.ndarray, acceleration: np.ndarray,
             pivot: np.ndarray) -> 'RigidFrame':
        """
        Return a rotation ``Q`` about an axis through ``pivot``.

        ``x -> Q (x - c) + c``, with ``Q'`` and ``Q''``.
        """
        return cls(rotation, rate, acceleration, pivot - rotation @ pivot, -(rate @ pivot),
                   -(acceleration @ pivot))

    def translated(self, offset: np.ndarray, velocity: np.ndarray, acceleration: np.ndarray
                   ) -> 'RigidFrame':
        """Return this motion followed by a translation (``x -> x + offset``)."""
        return RigidFrame(self.rotation, self.rotation_rate, self.rotation_acceleration,
                          self.translation + offset, self.velocity + velocity,
                          self.acceleration + acceleration)

    def then(self, other: 'RigidFrame') -> 'RigidFrame':
        """
        Return this motion followed by ``other`` (``x -> Q x + c`` with rates).

        Differentiated by the product rule.
        """
        q, dq, ddq = other.rotation, other.rotation_rate, other.rotation_acceleration
        r, dr, ddr = self.rotation, self.rotation_rate, self.rotation_acceleration
        b, db, ddb = self.translation, self.velocity, self.acceleration
        return RigidFrame(
            rotation=q @ r,
            rotation_rate=dq @ r + q @ dr,
            rotation_acceleration=ddq @ r + 2.0 * dq @ dr + q @ ddr,
            translation=q @ b + other.translation,
            velocity=dq @ b + q @ db + other.velocity,
            acceleration=ddq @ b + 2.0 * dq @ db + q @ ddb + other.acceleration)

    def restricted(self, index: tuple[np.ndarray, np.ndarray], axes: list[int]
                   ) -> 'RigidFrame':
        """
        Return the same motion on the scene's axes only.

        The same motion on the scene's axes only (``index = np.ix_(axes, axes)``; a 2D scene turns
        about its normal, so the in-plane block is the whole rotation of the plane).
        """
        return RigidFrame(self.rotation[index], self.rotation_rate[index],
                          self.rotation_acceleration[index], self.translation[axes],
                          self.velocity[axes], self.acceleration[axes])

    @functools.cached_property
    def angular_velocity(self) -> np.ndarray:
        """``W = R^T R'``: the angular velocity in the frame, as a cross-product matrix."""
        return self.rotation.T @ self.rotation_rate

    @functools.cached_property
    def angular_acceleration(self) -> np.ndarray:
        """
        Return ``A = R^T R'' = [alpha]x + [omega]x^2`` in the frame.

        The Euler and centrifugal accelerations of a point of the frame are ``A r``.
        """
        return self.rotation.T @ self.rotation_acceleration

    def carry(self, points: np.ndarray) -> np.ndarray:
        """(n, d) positions of points at ``points`` (n, d) in the frame."""
        return points @ self.rotation.T + self.translation

    def point_velocity(self, points: np.ndarray) -> np.ndarray:
        """(n, d) velocity of points held still at ``points`` (n, d) in the frame."""
        return points @ self.rotation_rate.T + self.velocity

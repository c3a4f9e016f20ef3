"""
A wrench (a force and a torque) pushing the free particles near a point, for a while.

A robot or a person pushes an object at a point with a force ``F`` and a torque ``T`` about
that point (``geometry_msgs/WrenchStamped`` at the origin of its frame). The object is a cloud
of particles, so the wrench is spread over the free particles within a radius of the point
(the nearest free particle alone when none is that close): of all the ways to spread it, the
one with the least sum of squared particle forces,

    f_i = a + b x r_i,    r_i = x_i - p,

whose six unknowns ``a``, ``b`` follow from ``sum f_i = F`` and ``sum r_i x f_i = T`` (a 6 x 6
system; least squares where the particles cannot carry every torque, such as one particle, or
particles on a line, about that line). The particle forces are fixed in the world's directions
for the wrench's time (an external load, like gravity or the pull), and capped as the pull is:
the force at ``max_force``, the torque at ``max_force`` times the radius.
"""
from __future__ import annotations

import dataclasses
import math
from typing import ClassVar

from modal_spring_ros.core.loads.base import Load, WorldPositions
from modal_spring_ros.core.loads.pull import nearest_free_particle
import numpy as np


class WrenchError(ValueError):
    """A wrench that cannot be applied (a value that is not finite, a radius out of range)."""


@dataclasses.dataclass(frozen=True)
class AppliedWrench(Load):
    """A wrench spread over the free particles near a point, fixed in world directions."""

    name: ClassVar[str] = 'wrench'
    particles: np.ndarray  # (k,) scene indices of the free particles it acts on
    dofs: np.ndarray       # (k d,) their free-DOF indices, particle by particle
    forces: np.ndarray     # (k, d) world force on each, on the scene's axes, N
    force: np.ndarray      # (3,) the total force applied (after the cap), N
    torque: np.ndarray     # (3,) the total torque about the point applied (after the cap), N m
    capped: bool           # whether the cap scaled the wrench down
    until: float           # simulation time it ends, s

    def world_forces(self, model, world_positions: WorldPositions, t: float
                     ) -> tuple[np.ndarray, np.ndarray] | None:
        return (self.dofs, self.forces.ravel()) if self.active(t) else None


def spread_wrench(offsets: np.ndarray, force: np.ndarray, torque: np.ndarray) -> np.ndarray:
    """
    Return the (k, 3) least-norm particle forces whose sum is ``force`` and moment ``torque``.

    ``offsets``: (k, 3) particle positions relative to the point the torque is taken about.
    """
    r = np.asarray(offsets, dtype=float)
    count = len(r)
    total = r.sum(axis=0)
    inertia = np.eye(3) * np.einsum('kd,kd->', r, r) - r.T @ r
    system = np.zeros((6, 6))
    system[:3, :3] = count * np.eye(3)
    system[:3, 3:] = -_cross_matrix(total)       # sum of b x r_i = -S x b
    system[3:, :3] = _cross_matrix(total)        # sum of r_i x a = S x a
    system[3:, 3:] = inertia                     # sum of r_i x (b x r_i)
    unknowns = np.linalg.lstsq(system, np.concatenate([force, torque]), rcond=1e-10)[0]
    return unknowns[:3] + np.cross(unknowns[3:], r)


def _cross_matrix(v: np.ndarray) -> np.ndarray:
    """Return ``[v]x``, the matrix of ``w -> v x w``."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def region(model, positions: np.ndarray, point: np.ndarray, radius: float) -> np.ndarray:
    """Return the free particles within ``radius`` of ``point``, or the nearest when none is."""
    free = model.free_particles
    inside = free[np.linalg.norm(positions[free] - point, axis=1) <= radius]
    return inside if inside.size else np.array([nearest_free_particle(model, positions, point)])


def make_wrench(model, positions: np.ndarray, point, force, torque, radius: float,
                max_force: float, now: float, hold_s: float) -> AppliedWrench:
    """
    Return ``force`` and ``torque`` (3,) at ``point`` (3,), from ``now`` for ``hold_s``.

    Spread over the free particles within ``radius`` of the point at ``positions`` (n, 3);
    capped at ``max_force`` N and ``max_force * radius`` N m.

    :raises WrenchError: a value that is not finite, a radius that is not positive, or a cap or
        duration that is negative.
    """
    point, force, torque = (np.asarray(v, dtype=float) for v in (point, force, torque))
    for name, value in (('point', point), ('force', force), ('torque', torque)):
        if value.shape != (3,) or not np.isfinite(value).all():
            raise WrenchError(f'wrench {name} must be three finite numbers')
    if not (math.isfinite(radius) and radius > 0.0):
        raise WrenchError(f'wrench radius ({radius}) must be finite and positive')
    for name, value in (('max_force', max_force), ('hold_s', hold_s)):
        if not (math.isfinite(value) and value >= 0.0):
            raise WrenchError(f'wrench {name} ({value}) must be finite and not negative')
    scale = min(1.0, _cap(force, max_force), _cap(torque, max_force * radius))
    force, torque = force * scale, torque * scale
    particles = region(model, positions, point, radius)
    spread = spread_wrench(positions[particles] - point, force, torque)
    slots = np.searchsorted(model.free_particles, particles)
    d = model.dimension
    dofs = (slots[:, None] * d + np.arange(d)).ravel()
    return AppliedWrench(particles, dofs, spread[:, model.axes], force, torque, scale < 1.0,
                         float(now + hold_s))


def _cap(vector: np.ndarray, limit: float) -> float:
    size = float(np.linalg.norm(vector))
    return limit / size if size > limit else 1.0


def default_radius(model) -> float:
    """One and a half times the median spring rest length: a particle and its neighbours."""
    return 1.5 * float(np.median(model.scene.rest_length))

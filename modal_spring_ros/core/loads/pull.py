"""
A person pulling one particle toward a point for a while (RViz's "Publish Point").

The particle is pulled by a spring of ``stiffness`` toward ``target`` (world coordinates on the
scene's axes), its force capped at ``max_force`` so that a click far away cannot tear the
sheet, until the simulation time ``until``. The force is an external load like gravity: the
simulation projects it on its coordinates, and the clamp and the band behave as usual.
"""
from __future__ import annotations

import dataclasses
import math
from typing import ClassVar

from modal_spring_ros.core.loads.base import Load, WorldPositions
import numpy as np

#: Smallest margin of the reach around a scene's rest shape, m (a scene of one point has one).
REACH_MIN_M = 1.0


class PullError(ValueError):
    """A pull that cannot be applied (a fixed particle, a value out of range)."""


@dataclasses.dataclass(frozen=True)
class Pull(Load):
    """A free particle pulled toward a world point by a capped spring."""

    name: ClassVar[str] = 'pull'
    particle: int          # scene index of a free particle
    slot: int              # its position among the free particles
    target: np.ndarray     # (d,) world point it is pulled toward
    stiffness: float       # N/m
    max_force: float       # N
    until: float           # simulation time the pull ends, s

    def force(self, position: np.ndarray, t: float) -> np.ndarray | None:
        """
        (d,) world force on the particle at ``position`` at time ``t``.

        Or None once the pull is over.
        """
        if t > self.until:
            return None
        f = self.stiffness * (self.target - position)
        size = math.sqrt(float(f @ f))
        if size > self.max_force:
            f *= self.max_force / size
        return f

    def world_forces(self, model, world_positions: WorldPositions, t: float
                     ) -> tuple[np.ndarray, np.ndarray] | None:
        f = self.force(world_positions(np.array([self.slot]))[0], t)
        if f is None:
            return None
        d = model.dimension
        return np.arange(self.slot * d, (self.slot + 1) * d), f


def nearest_free_particle(model, positions: np.ndarray, point: np.ndarray) -> int:
    """Return the scene index of the free particle nearest to ``point`` (3,) at ``positions``."""
    free = model.free_particles
    distance = np.einsum('nd,nd->n', positions[free] - point, positions[free] - point)
    return int(free[int(np.argmin(distance))])


def make_pull(model, particle: int, point, stiffness: float, max_force: float, now: float,
              hold_s: float) -> Pull:
    """
    Return a pull of scene particle ``particle`` toward ``point`` (3,).

    A pull of scene particle ``particle`` toward ``point`` (3,) from ``now`` for ``hold_s``
    seconds.

    :raises PullError: the particle is fixed or out of range, or a value is not finite and
        non-negative.
    """
    point = np.asarray(point, dtype=float)
    for name, value in (('stiffness', stiffness), ('max_force', max_force),
                        ('hold_s', hold_s)):
        if not (math.isfinite(value) and value >= 0.0):
            raise PullError(f'pull {name} ({value}) must be finite and not negative')
    if point.shape != (3,) or not np.isfinite(point).all():
        raise PullError('pull point must be three finite coordinates')
    slots = np.flatnonzero(model.free_particles == particle)
    if not slots.size:
        raise PullError(f'particle {particle} is fixed or does not exist: it cannot be pulled')
    return Pull(int(particle), int(slots[0]), within_reach(model, point[model.axes]),
                float(stiffness), float(max_force), float(now + hold_s))


def within_reach(model, target: np.ndarray) -> np.ndarray:
    """
    Return ``target`` (on the scene's axes) moved into the scene's reach.

    The reach is the box of the rest shape grown by its own size (at least ``REACH_MIN_M``) on
    every side: a point further away pulls no harder than one at its edge (the force is capped
    anyway), and a point like -1e308 can no longer overflow the pull's spring (inf x 0 = NaN).
    """
    low, high = model.rest.min(axis=0), model.rest.max(axis=0)
    grow = max(float(np.max(high - low)), REACH_MIN_M)
    return np.clip(np.asarray(target, dtype=float), low - grow, high + grow)

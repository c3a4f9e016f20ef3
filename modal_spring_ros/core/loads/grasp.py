"""
Grippers that close on the object, hold what is within their reach, and let go when they open.

A gripper is a frame (a robot's tool, from TF: :meth:`~modal_spring_ros.core.loads.holder.
LoadHolder.move_frame` tells the run where it is). Closing it takes the free particles within
``reach`` of its origin and keeps each where it was in the gripper's frame: a stiff spring
(the run's penalty, :func:`~modal_spring_ros.core.loads.contact.penalty`: ``k = m (c / dt)^2``
up to ``c = 1``, half-critical damping on its stretch's change) pulls it to that point as the
frame moves.
Opening it lets them go. Several grippers hold at once (two fold a towel), each its own
:class:`Hold` in the run's one :class:`Grasp`; a particle two grippers hold is pulled by both.

A hold's spring pulls a particle to within ``F dt^2 / (m c^2)`` of its point under a force
``F`` (the contact's penetration bound): a gripper holds as firmly as the run's step allows.
"""
from __future__ import annotations

import dataclasses
import math
from typing import ClassVar

from modal_spring_ros.core.loads.base import Load, WorldPositions
from modal_spring_ros.core.loads.contact import free_points
from modal_spring_ros.core.model.colliders import Pose
import numpy as np


class GraspError(ValueError):
    """A gripper that cannot close: its frame's pose is not known, or nothing is within reach."""


@dataclasses.dataclass(frozen=True, eq=False)
class Hold:
    """What one closed gripper holds: free-particle slots and their points in its frame."""

    frame: str
    pose: Pose
    slots: np.ndarray        # (k,) positions among the free particles
    offsets: np.ndarray      # (k, 3) where each is held, in the gripper's frame
    stretch: np.ndarray      # (k, 3) held point minus position at the last step (world)

    def targets(self) -> np.ndarray:
        """Return the held points in the world, (k, 3)."""
        return self.pose.to_world(self.offsets) + self.pose.translation


@dataclasses.dataclass(frozen=True, eq=False)
class Grasp(Load):
    """The run's closed grippers, each a :class:`Hold`."""

    name: ClassVar[str] = 'grasp'
    keeps_state: ClassVar[bool] = True
    holds: tuple[Hold, ...]
    stiffness: np.ndarray    # (free,) N/m
    damping: np.ndarray      # (free,) N s/m
    dt: float
    until: float = math.inf

    def world_forces(self, model, world_positions: WorldPositions, t: float):
        if not self.holds:
            return None
        d = model.dimension
        dofs, forces = [], []
        for hold in self.holds:
            stretch = hold.targets() - free_points(model, world_positions, hold.slots)
            k, c = self.stiffness[hold.slots, None], self.damping[hold.slots, None]
            f = k * stretch + c * (stretch - hold.stretch) / self.dt
            dofs.append((hold.slots[:, None] * d + np.arange(d)).ravel())
            forces.append(f[:, list(model.axes)].ravel())
        return np.concatenate(dofs), np.concatenate(forces)

    def stepped(self, model, world_positions: WorldPositions, t: float) -> 'Grasp':
        """Return the grasp after a step: each hold's stretch where the step ended."""
        return dataclasses.replace(self, holds=tuple(
            dataclasses.replace(h, stretch=h.targets() - free_points(model, world_positions,
                                                                     h.slots))
            for h in self.holds))

    def moved(self, frame: str, pose: Pose) -> 'Grasp':
        """Return the grasp with the gripper on ``frame`` where ``pose`` puts it."""
        return dataclasses.replace(self, holds=tuple(
            dataclasses.replace(h, pose=pose) if h.frame == frame else h for h in self.holds))

    def opened(self, frame: str) -> 'Grasp':
        """Return the grasp without the gripper on ``frame``'s hold."""
        return dataclasses.replace(self, holds=tuple(h for h in self.holds if h.frame != frame))

    def held(self, frame: str) -> int:
        """Return how many particles the gripper on ``frame`` holds (0: open)."""
        return sum(int(h.slots.size) for h in self.holds if h.frame == frame)

    def describe(self) -> str:
        """Return what is held, as text (``left_tool holds 4 particles``)."""
        return ', '.join(f'{h.frame} holds {h.slots.size} particles' for h in self.holds)


def closed_on(grasp: Grasp | None, model, positions: np.ndarray, frame: str, pose: Pose,
              reach: float, stiffness: np.ndarray, damping: np.ndarray, dt: float) -> Grasp:
    """
    Return ``grasp`` (None: none yet) with the gripper on ``frame`` closed where ``pose`` is.

    It holds the free particles within ``reach`` of its origin at ``positions`` (n, 3), each
    where it is (a gripper closed again takes what is within reach now).

    :raises GraspError: nothing is within reach.
    """
    free = model.free_particles
    distance = np.linalg.norm(positions[free] - pose.translation, axis=1)
    slots = np.flatnonzero(distance <= reach)
    if not slots.size:
        nearest = float(distance.min()) if distance.size else math.inf
        raise GraspError(f'nothing within reach of {frame} ({reach:.3g} m; the nearest free '
                         f'particle is {nearest:.3g} m away)')
    hold = Hold(frame, pose, slots, pose.into_frame(positions[free[slots]]),
                np.zeros((slots.size, 3)))
    base = (grasp if grasp is not None else Grasp((), stiffness, damping, float(dt)))
    return dataclasses.replace(base.opened(frame), holds=base.opened(frame).holds + (hold,))

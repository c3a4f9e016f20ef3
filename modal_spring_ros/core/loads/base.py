"""
The load contract: what acts on particles from outside the scene, and while it lasts.

A load gives forces on free DOFs in the world's directions (on the scene's axes) from the
particles' world positions at a time; the run turns them into the frame it steps in and adds
them (a modal run projects them on its coordinates: :mod:`~modal_spring_ros.core.loads.applied`).
It is immutable: a change is a new load set on the run under its :attr:`Load.name`. A load whose
forces depend on what happened before (contact: where a particle first touched) says so with
:attr:`Load.keeps_state`, and the run replaces it after every step by :meth:`Load.stepped`.
"""
from __future__ import annotations

import abc
from typing import Callable, ClassVar

import numpy as np

#: ``world_positions(slots)``: the (k, d) world positions of the free particles at those slots
#: (their positions among the free particles), on the scene's axes; ``world_positions()``: of
#: every free particle, in order
WorldPositions = Callable[..., np.ndarray]


class Load(abc.ABC):
    """A load on the free particles, in the world's directions, until ``until`` (s)."""

    #: the run holds one load under each name (a new pull replaces the pull)
    name: ClassVar[str]
    #: simulation time the load ends, s
    until: float
    #: the load changes with every step (:meth:`stepped`)
    keeps_state: ClassVar[bool] = False

    def active(self, t: float) -> bool:
        """Tell whether the load acts at simulation time ``t``."""
        return t <= self.until

    @abc.abstractmethod
    def world_forces(self, model, world_positions: WorldPositions, t: float
                     ) -> tuple[np.ndarray, np.ndarray] | None:
        """
        Return (free-DOF indices, their forces) at ``t``, in world directions, or None.

        ``model``: the run's :class:`~modal_spring_ros.core.model.model.MassSpringModel`. An
        index may appear twice (the forces add).
        """

    def stepped(self, model, world_positions: WorldPositions, t: float) -> 'Load':
        """Return the load after a step that ended at ``t`` in these positions (itself: none)."""
        return self

"""A run's state at one instant, kept apart from the run (what ``Simulation.take_over`` reads)."""
from __future__ import annotations

import dataclasses

import numpy as np


@dataclasses.dataclass(frozen=True)
class RunState:
    """
    A run's time, free-DOF displacement and velocity (in the clamp's frame), loads and poses.

    A copy: the run goes on stepping, the state stays. Another run continues from it with
    ``other.take_over(state)``.
    """

    time: float
    u: np.ndarray
    v: np.ndarray
    loads: dict
    frame_poses: dict

    @classmethod
    def of(cls, sim) -> 'RunState':
        """Return the state ``sim`` (a :class:`Simulation`) is in now."""
        return cls(sim.time, sim.displacement(), sim.velocity(), dict(sim.loads),
                   dict(sim.frame_poses))

    def displacement(self) -> np.ndarray:
        """Return the free-DOF displacement."""
        return self.u

    def velocity(self) -> np.ndarray:
        """Return the free-DOF velocity."""
        return self.v

    def displaced(self, by: np.ndarray) -> 'RunState':
        """Return this state with its displacement moved ``by`` (free DOF)."""
        return dataclasses.replace(self, u=self.u + by)

"""
The seat every method steps its loads through: each load's forces in the frame it steps in.

Loads are given in world directions (:mod:`~modal_spring_ros.core.loads.base`); every method
steps in the clamp's frame or in the world's, so the seat hands each load the particles' world
positions and turns its forces into the frame the method steps in, returned as values on free
DOFs, which the method adds (a modal run projects them on its shapes).
"""
from __future__ import annotations

from typing import Callable, Mapping

from modal_spring_ros.core.loads.base import Load
import numpy as np


def applied_loads(model, loads: Mapping[str, Load],
                  displacement: Callable[[np.ndarray], np.ndarray], t: float,
                  in_world: bool = False) -> tuple[np.ndarray, np.ndarray] | None:
    """
    Return (free-DOF indices, forces) of every active load at ``t``, or None.

    ``displacement(dofs)`` gives the displacement of those free DOFs (in the frame the method
    steps in; ``dofs`` None: every free DOF, in order); the forces are in the clamp's frame,
    or the world's with ``in_world`` (a method stepping world coordinates). An index may appear
    twice: add with ``np.add.at`` or a product.
    """
    active = [load for load in loads.values() if load.active(t)]
    if not active:
        return None
    world_positions, frame = _world_positions(model, displacement, t, in_world)
    d = model.dimension
    dofs, forces = [], []
    for load in active:
        found = load.world_forces(model, world_positions, t)
        if found is not None:
            index, f = found
            dofs.append(index)
            forces.append(f if frame is None else (f.reshape(-1, d) @ frame.rotation).ravel())
    if not dofs:
        return None
    return np.concatenate(dofs), np.concatenate(forces)


def stepped_loads(model, loads: Mapping[str, Load],
                  displacement: Callable[[np.ndarray], np.ndarray], t: float,
                  in_world: bool = False) -> dict[str, Load]:
    """Return ``loads`` after a step that ended at ``t`` (those that keep a state stepped)."""
    world_positions, _ = _world_positions(model, displacement, t, in_world)
    return {name: load.stepped(model, world_positions, t) if load.keeps_state else load
            for name, load in loads.items()}


def of_vector(u: np.ndarray) -> Callable[[np.ndarray | None], np.ndarray]:
    """Return the ``displacement(dofs)`` of a vector of every free DOF's displacement ``u``."""
    return lambda dofs: u if dofs is None else u[dofs]


def of_shapes(phi: np.ndarray, q: np.ndarray) -> Callable[[np.ndarray | None], np.ndarray]:
    """Return the ``displacement(dofs)`` of coordinates ``q`` on shapes ``phi`` (rows: DOFs)."""
    return lambda dofs: phi @ q if dofs is None else phi[dofs] @ q


def _world_positions(model, displacement: Callable[[np.ndarray], np.ndarray], t: float,
                     in_world: bool):
    """Return ``world_positions(slots)`` of the free particles at ``t``, and the clamp's frame."""
    frame = None if in_world or model.motion.is_static else model.frame(t)
    d = model.dimension
    free = model.free_particles

    def world_positions(slots: np.ndarray | None = None) -> np.ndarray:
        if slots is None:      # every free particle: no gather (a modal run's one product)
            x = model.rest[free] + displacement(None).reshape(-1, d)
        else:
            dofs = (slots[:, None] * d + np.arange(d)).ravel()
            x = model.rest[free[slots]] + displacement(dofs).reshape(-1, d)
        return x if frame is None else frame.carry(x)
    return world_positions, frame

"""
The loads a person or a robot applies to a run: a pull on one particle, a wrench on a region.

Both are given in world directions (:mod:`~modal_spring_ros.core.motion.pull`,
:mod:`~modal_spring_ros.core.motion.wrench`); every method steps in the clamp's frame or in
the world's, so the loads are turned into the frame the method steps in and returned as values
on free DOFs, which the method adds (a modal run projects them on its shapes).
"""
from __future__ import annotations

from typing import Callable

from modal_spring_ros.core.motion.pull import Pull
from modal_spring_ros.core.motion.wrench import AppliedWrench
import numpy as np


def applied_loads(model, pull: Pull | None, wrench: AppliedWrench | None,
                  displacement: Callable[[np.ndarray], np.ndarray], t: float,
                  in_world: bool = False) -> tuple[np.ndarray, np.ndarray] | None:
    """
    Return (free-DOF indices, forces) of the pull and the wrench at ``t``, or None.

    ``displacement(dofs)`` gives the displacement of those free DOFs (in the frame the method
    steps in); the forces are in the clamp's frame, or the world's with ``in_world`` (a method
    stepping world coordinates). An index may appear twice: add with ``np.add.at`` or a product.
    """
    pulled = pull is not None and t <= pull.until
    pushed = wrench is not None and t <= wrench.until
    if not (pulled or pushed):
        return None
    frame = None if in_world or model.scene.anchor_motion.is_static else model.frame(t)
    dofs, forces = [], []
    if pulled:
        d = model.dimension
        index = np.arange(pull.slot * d, (pull.slot + 1) * d)
        x = model.rest[pull.particle] + displacement(index)
        f = pull.force(x if frame is None else frame.carry(x), t)
        if f is not None:
            dofs.append(index)
            forces.append(f if frame is None else f @ frame.rotation)
    if pushed:
        f = wrench.forces if frame is None else wrench.forces @ frame.rotation
        dofs.append(wrench.dofs)
        forces.append(f.ravel())
    if not dofs:
        return None
    return np.concatenate(dofs), np.concatenate(forces)

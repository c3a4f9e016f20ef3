"""What stepping one set of a modal run's coordinates needs, built once per set."""
from __future__ import annotations

import dataclasses

from modal_spring_ros.core.forces import (build_forces, ExactForces, ForceContext, ForceModel,
                                          ForceOptions)
from modal_spring_ros.core.integrators import DiagonalOperators
from modal_spring_ros.core.integrators.base import ROUNDOFF_SHARE
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.model.scene import Damping
from modal_spring_ros.core.motion.frame_loads import FrameLoads
from modal_spring_ros.core.simulations.coordinates import AddedCoordinateBank
import numpy as np


@dataclasses.dataclass(frozen=True)
class SteppedSet:
    """Shapes, ``omega^2``, damping, operators and forces of one set of coordinates."""

    phi: np.ndarray
    omega2: np.ndarray
    damping: np.ndarray
    ops: DiagonalOperators
    forces: ForceModel
    frame: FrameLoads | None   # a turning clamp's inertial loads on these coordinates
    frame_shapes: np.ndarray   # the shapes for the frames (model.frame_shapes), with the set

    @classmethod
    def build(cls, model: MassSpringModel, bank: AddedCoordinateBank, modes: np.ndarray,
              damping: Damping, forces: ForceOptions, dt: float,
              strain_limit: float, ratios: np.ndarray | None = None) -> 'SteppedSet':
        """
        Return the set of coordinates ``modes`` (rest or added, from ``bank``).

        ``ratios``: a modal damping ratio per coordinate that replaces ``damping`` where it is
        not NaN (``C_i = 2 h_i omega_i``).

        Its forces are the model ``forces`` names, built with the basis's services (progress,
        worker process, sample store).
        """
        phi, omega = bank.columns(modes)
        damp = damping.modal_coefficients(omega)
        if ratios is not None:
            own = ~np.isnan(ratios)
            damp[own] = 2.0 * ratios[own] * omega[own]
        exact = ExactForces(model, phi, bank.load_mask(modes))
        basis = bank.basis
        context = ForceContext(exact, phi, omega**2, damp, dt, strain_limit, bank.progress,
                               basis.worker, basis.samples)
        floor = ROUNDOFF_SHARE * float(np.max(np.abs(exact.gravity()), initial=0.0))
        return cls(phi, omega**2, damp, DiagonalOperators(1.0, damp, omega**2, dt, floor),
                   build_forces(context, forces), exact.frame, model.frame_shapes(phi))

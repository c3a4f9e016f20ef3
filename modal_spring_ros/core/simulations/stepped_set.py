"""What stepping one set of a modal run's coordinates needs, built once per set."""
from __future__ import annotations

import dataclasses
import math

from modal_spring_ros.core.forces import GeneralizedForces
from modal_spring_ros.core.frame_loads import FrameLoads
from modal_spring_ros.core.integrators import DiagonalOperators
from modal_spring_ros.core.model import MassSpringModel
from modal_spring_ros.core.refreshed_forces import RefreshedForces
from modal_spring_ros.core.sampled_forces import cached_sample, SampledForces
from modal_spring_ros.core.scene import Damping
from modal_spring_ros.core.simulations.coordinates import AddedCoordinateBank
import numpy as np


@dataclasses.dataclass(frozen=True)
class SteppedSet:
    """Shapes, ``omega^2``, damping, operators and forces of one set of coordinates."""

    phi: np.ndarray
    omega2: np.ndarray
    damping: np.ndarray
    ops: DiagonalOperators
    forces: GeneralizedForces | RefreshedForces | SampledForces
    frame: FrameLoads | None   # a turning clamp's inertial loads on these coordinates
    phi32: np.ndarray          # the shapes in float32, for the frames (made with the set)

    @classmethod
    def build(cls, model: MassSpringModel, bank: AddedCoordinateBank, modes: np.ndarray,
              damping: Damping, force_refresh: int, dt: float, strain_limit: float,
              sample_tolerance: float | None = None, progress=None,
              force_tolerance: float = math.inf) -> 'SteppedSet':
        """
        Return the set of coordinates ``modes`` (rest or added, from ``bank``).

        With ``sample_tolerance``, the springs sampled within it (trained, or from the cache);
        refreshed forces fall back to exact ones past ``force_tolerance``.
        """
        phi, omega = bank.columns(modes)
        damp = damping.modal_coefficients(omega)
        exact = GeneralizedForces(model, phi, bank.load_mask(modes))
        if sample_tolerance is not None:
            sample = cached_sample(exact, phi, omega**2, damp, dt, sample_tolerance, progress,
                                   bank.basis.worker)
            forces = SampledForces(exact, sample, sample_tolerance)
        elif force_refresh == 1:
            forces = exact
        else:
            forces = RefreshedForces(exact, omega**2, force_refresh, dt, strain_limit,
                                     force_tolerance)
        return cls(phi, omega**2, damp, DiagonalOperators(1.0, damp, omega**2, dt), forces,
                   exact.frame, phi.astype(np.float32))

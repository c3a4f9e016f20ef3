"""
The full run of a turning clamp, in the world: the reference the floating frame is checked against.

The modal run writes a turning body in its clamp's frame and adds the frame's inertial loads
(:mod:`modal_spring_ros.core.motion.frame_loads`). The full run does none of that: it steps the
free particles' world positions, and the fixed particles simply sit where the clamp carries them,
so the springs that reach the clamp pull with the clamp's true motion. Being independent of the
frame's algebra, it checks it.

Damping acts on the velocity relative to the clamp's frame (a rigid turn is not damped, as in
the modal run): ``-R C R^T (x' - v_frame(x))``, with ``C`` the rest damping and
``v_frame(x) = R' R^T (x - b) + b'``. Since the lumped mass is the same in every direction,
``M + dt/2 R C R^T = R (M + dt/2 C) R^T``: the rest operators serve, turned per particle.
"""
from __future__ import annotations

from modal_spring_ros.core.forces.exact import ExactForces
from modal_spring_ros.core.forces.springs import spring_difference_matrix
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.motion.rigid_frame import RigidFrame
import numpy as np


class PrescribedClampForces(ExactForces):
    """
    Force on the free DOF in world coordinates (``x = X + u``).

    Force on the free DOF in world coordinates (``x = X + u``) with the fixed particles at their
    prescribed positions, and gravity; no inertial load (the world is inertial).
    """

    def __init__(self, model: MassSpringModel):
        super().__init__(model, None)
        s = model.scene
        fixed_index = np.full(s.n_particles, -1)
        fixed_index[model.fixed_particles] = np.arange(model.fixed_particles.size)
        self._fixed_difference = spring_difference_matrix(
            s.springs, fixed_index, model.dimension, model.fixed_particles.size)
        self._rest_deltas = self._delta_rest.copy()
        self._fixed_rest = model.rest[model.fixed_particles]
        self._model = model
        self._bend_rest = None if self._bend_const is None else self._bend_const.copy()

    def __call__(self, u: np.ndarray, t: float) -> np.ndarray:
        moved = self._model.frame(t).carry(self._fixed_rest) - self._fixed_rest
        self._delta_rest = self._rest_deltas + self._fixed_difference @ moved.ravel()
        if self._bend_rest is not None:  # the bending's pull of the moved fixed particles
            self._bend_const = self._bend_rest - self._model.bending_fixed @ moved.ravel()
        return super().__call__(u, t)

    def loads(self, t: float) -> np.ndarray:
        return self.gravity()


class WorldFrameRun:
    """
    Forces and turned operators of the full run of a turning clamp.

    Forces and turned operators of the full run of a turning clamp (the
    :class:`~modal_spring_ros.core.integrators.Operators` of one step, once :meth:`at` has set the
    step's time).
    """

    def __init__(self, model: MassSpringModel, ops):
        self.model = model
        self.forces = PrescribedClampForces(model)
        self._ops = ops
        #: what an implicit step's iteration may leave (turning does not change its size)
        self.acceleration_floor = ops.acceleration_floor
        self._free_rest = model.rest[model.free_particles]
        self._frame = model.frame(0.0)

    def at(self, t: float) -> 'WorldFrameRun':
        """Use the clamp's frame at ``t`` (the end of the step being taken)."""
        self._frame = self.model.frame(t)
        return self

    # -- the step's operators (rest operators, turned per particle) -------------------------
    def damp(self, v: np.ndarray) -> np.ndarray | float:
        damped = self._ops.damp(self._into(v))
        return damped if np.isscalar(damped) else self._out(damped)

    def stiff(self, u: np.ndarray) -> np.ndarray:
        return self._out(self._ops.stiff(self._into(u)))

    def explicit_acceleration(self, force: np.ndarray, v_pred: np.ndarray) -> np.ndarray:
        return self._out(self._ops.explicit_acceleration(self._into(force),
                                                         self._into(v_pred)))

    def solve_average(self, rhs: np.ndarray) -> np.ndarray:
        return self._out(self._ops.solve_average(self._into(rhs)))

    # -- forces and states ------------------------------------------------------------------
    def force(self, u: np.ndarray, t: float) -> np.ndarray:
        """
        Springs and gravity at world displacement ``u``.

        Plus the damping of the frame's own velocity there (so that damping acts on the velocity
        relative to the frame).
        """
        self.at(t)
        f = self.forces(u, t)
        return f + self.damp(self._frame_velocity(u, self._frame))

    def to_frame(self, u: np.ndarray, v: np.ndarray, t: float
                 ) -> tuple[np.ndarray, np.ndarray]:
        """World displacement and velocity of the free DOF -> the clamp's frame's."""
        frame, d = self.model.frame(t), self.model.dimension
        y = (self._free_world(u) - frame.translation) @ frame.rotation
        relative = (v.reshape(-1, d) - frame.point_velocity(y)) @ frame.rotation
        return (y - self._free_rest).ravel(), relative.ravel()

    def to_world(self, u: np.ndarray, v: np.ndarray, t: float
                 ) -> tuple[np.ndarray, np.ndarray]:
        """Displacement and velocity in the clamp's frame -> the world's."""
        x = self.model.positions(u, t)[self.model.free_particles]
        return ((x - self._free_rest).ravel(), self.model.world_velocity(u, v, t))

    def positions(self, u: np.ndarray, t: float) -> np.ndarray:
        """
        Return every particle's (n, d) world position at world displacement ``u``.

        The free particles where they are, the fixed ones where the clamp carries them: no
        round trip through the clamp's frame (a frame written every step paid it every step).
        """
        x = self.model.rest.copy()
        fixed = self.model.fixed_particles
        x[fixed] = self.model.frame(t).carry(x[fixed])
        x[self.model.free_particles] = self._free_world(u)
        return x

    def _free_world(self, u: np.ndarray) -> np.ndarray:
        """Return the free particles' (p, d) world positions at world displacement ``u``."""
        return self._free_rest + u.reshape(-1, self.model.dimension)

    def _frame_velocity(self, u: np.ndarray, frame: RigidFrame) -> np.ndarray:
        y = (self._free_world(u) - frame.translation) @ frame.rotation
        return frame.point_velocity(y).ravel()

    def _into(self, v: np.ndarray) -> np.ndarray:
        """World components -> the frame's (``R^T`` per particle)."""
        d = self.model.dimension
        return (v.reshape(-1, d) @ self._frame.rotation).ravel()

    def _out(self, v: np.ndarray) -> np.ndarray:
        d = self.model.dimension
        return (v.reshape(-1, d) @ self._frame.rotation.T).ravel()

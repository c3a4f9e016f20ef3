"""
The mass-spring model of a scene: DOF layout, nonlinear spring forces (paper eq. 20), energy.

:class:`MassSpringModel` precomputes everything that does not change while stepping (index
arrays, the sparse spring-to-particle scatter matrix, lumped masses, the rest stiffness), so
that a force evaluation is a handful of vectorised numpy operations (see
:mod:`modal_spring_ros.core.forces.exact`).

DOF layout: the free (not fixed) particles in scene order, ``dimension`` coordinates each;
displacement vectors ``u`` are flat arrays of length ``n_free * dimension``.
"""
from __future__ import annotations

import functools

from modal_spring_ros.core.forces.exact import ExactForces
from modal_spring_ros.core.forces.springs import spring_difference_matrix
from modal_spring_ros.core.laws import scene_law
from modal_spring_ros.core.model.scene import Scene
from modal_spring_ros.core.model.stiffness import assemble_stiffness, reduce_to_free
from modal_spring_ros.core.motion.clamp_motion import ClampMotion
from modal_spring_ros.core.motion.rigid_frame import RigidFrame
import numpy as np
import scipy.sparse as sp


class MassSpringModel:
    """
    Vectorised mechanics of one scene, and how its clamp moves in this run.

    ``motion`` is the clamp's motion when it is not the scene's own ``anchor_motion``: a
    :class:`~modal_spring_ros.core.motion.clamp_follower.ClampFollower` that follows the poses
    a run is given (input state belongs to the run, never to the scene, which stays data).
    """

    def __init__(self, scene: Scene, motion: ClampMotion | None = None):
        self.scene = scene
        #: the clamp's motion: the scene's, or the poses this run follows
        self.motion: ClampMotion = scene.anchor_motion if motion is None else motion
        d = scene.dimension
        self.dimension = d
        self.axes = list(scene.axes)
        self.free_particles = np.flatnonzero(~scene.fixed)
        self.fixed_particles = np.flatnonzero(scene.fixed)
        self.n_free_dof = self.free_particles.size * d
        self.free_dof = (self.free_particles[:, None] * d + np.arange(d)).ravel()
        self.rest = np.ascontiguousarray(scene.rest_positions[:, self.axes], dtype=float)
        self._i = np.ascontiguousarray(scene.springs[:, 0])
        self._j = np.ascontiguousarray(scene.springs[:, 1])
        #: the springs' law (:mod:`modal_spring_ros.core.laws`), bound to their k and l
        self.law = scene_law(scene)
        self._l = self.law.rest_length
        #: lumped mass per free DOF
        self.mass_dof = np.repeat(scene.mass[self.free_particles], d)
        self.gravity_force = (scene.mass[self.free_particles][:, None]
                              * scene.gravity[None, self.axes]).ravel()
        self._inv_l = 1.0 / self._l
        self._frame: tuple[tuple[float, int], RigidFrame] | None = None
        self._axes_index = np.ix_(self.axes, self.axes)

    @property
    def free_points(self) -> np.ndarray:
        """Return the free particles' rest positions (p, d), in their free DOF's order."""
        return self.rest[self.free_particles]

    # -- stiffness and mass at rest ------------------------------------------------------------
    @functools.cached_property
    def omega_bound(self) -> float:
        """
        Return a bound on the highest circular frequency at rest, rad/s (Gershgorin's).

        The largest absolute row sum of ``M^-1/2 K M^-1/2``, square-rooted: never below the
        highest mode's, found without an eigensolve.
        """
        scale = sp.diags(1.0 / np.sqrt(self.mass_dof))
        a = abs(scale @ self.stiffness_free @ scale)
        return float(np.sqrt(np.asarray(a.sum(axis=1)).max(initial=0.0)))

    @functools.cached_property
    def stiffness_free(self) -> sp.csr_matrix:
        """
        Sparse stiffness at the reference shape, reduced to the free DOF (symmetric).

        The rest stiffness (positive semi-definite); about a loaded shape, the tangent stiffness
        with the springs' tension (:func:`~.stiffness.assemble_stiffness`).
        """
        s = self.scene
        full = assemble_stiffness(s.rest_positions[:, self.axes], s.springs, self.law,
                                  s.dimension, stretched=s.loaded)
        stiffness = reduce_to_free(full, self.free_dof)
        if self.bending_free is not None:
            stiffness = (stiffness + self.bending_free).tocsr()
        return stiffness

    # -- bending (a surface flat as built) -----------------------------------------------------
    @functools.cached_property
    def _bending_matrix(self) -> sp.csr_matrix | None:
        """``kron(B, I_d)`` on every particle's coordinates, or None without bending."""
        bending = self.scene.bending
        if bending is None or not bending.count:
            return None
        return sp.kron(bending.matrix(self.scene.n_particles), sp.identity(self.dimension),
                       format='csr')

    @functools.cached_property
    def bending_free(self) -> sp.csr_matrix | None:
        """Return the bending's (constant) stiffness on the free DOF, or None without bending."""
        if self._bending_matrix is None:
            return None
        return reduce_to_free(self._bending_matrix, self.free_dof)

    @functools.cached_property
    def bending_fixed(self) -> sp.csr_matrix | None:
        """Return the bending's rows of the free DOF, columns of the fixed DOF (None: none)."""
        if self._bending_matrix is None:
            return None
        fixed = (self.fixed_particles[:, None] * self.dimension
                 + np.arange(self.dimension)).ravel()
        return self._bending_matrix[self.free_dof][:, fixed].tocsr()

    @functools.cached_property
    def bending_rest_force(self) -> np.ndarray | None:
        """Return the bending force on the free DOF at the reference shape (None: no bending)."""
        if self._bending_matrix is None:
            return None
        return -(self._bending_matrix @ self.rest.ravel())[self.free_dof]

    @functools.cached_property
    def spring_difference(self) -> sp.csr_matrix:
        """
        Return the sparse spring-difference matrix ``D``.

        Per spring and axis, ``u_j - u_i`` of a free-DOF displacement ``u`` (component-major rows:
        every spring's x, then every y, ...).
        """
        s = self.scene
        free_index = np.full(s.n_particles, -1)
        free_index[self.free_particles] = np.arange(self.free_particles.size)
        return spring_difference_matrix(s.springs, free_index, self.dimension,
                                        self.free_particles.size)

    # -- positions ---------------------------------------------------------------------------
    @property
    def rotates(self) -> bool:
        """Tell whether the clamp turns: displacements live in its (floating) frame."""
        return self.motion.rotates

    def frame(self, t: float) -> RigidFrame:
        """
        Return the clamp's rigid motion at ``t`` on the scene's axes.

        The clamp's rigid motion at ``t`` on the scene's axes (the last one is kept: the same time
        is asked for by the forces, the positions and the energy; a clamp following poses changes
        its revision when it gets a new one).
        """
        motion = self.motion
        key = (t, motion.revision)
        cached = self._frame
        if cached is not None and cached[0] == key:
            return cached[1]
        frame = motion.frame(t).restricted(self._axes_index, self.axes)
        self._frame = (key, frame)
        return frame

    def restart_clamp(self) -> None:
        """Go back to t = 0 with the run: so does a clamp with a state of its own."""
        self.motion.restart()

    def anchor_offset(self, t: float) -> np.ndarray:
        """
        Return the (d,) rigid offset of the base (every fixed particle) at time ``t``.

        The offset of a clamp that only translates.
        """
        return self.motion.offset(t)[self.axes]

    def positions(self, u: np.ndarray, t: float) -> np.ndarray:
        """
        Return the (n, d) positions for displacement ``u`` in the clamp's frame at ``t``.

        ``x = R (X + u) + b``; ``X + u + p`` when the clamp only translates.
        """
        if self.rotates:
            y = self.rest.copy()
            y.reshape(-1)[self.free_dof] += u
            return self.frame(t).carry(y)
        x = self.rest + self.anchor_offset(t)
        x.reshape(-1)[self.free_dof] += u  # flat index: several times faster than by rows
        return x

    def frame_shapes(self, phi: np.ndarray) -> np.ndarray:
        """
        Return the shapes ``phi`` in float32, laid out axis by axis over every particle.

        Row ``k n + i`` holds particle ``i``'s shape along the scene's ``k``-th axis (zeros for a
        clamped particle), so ``shapes @ q`` is every particle's movement axis by axis: what
        :meth:`write_movement` writes for a frame, with no scatter. Float32 halves the memory a
        frame reads; a frame's values are float32.
        """
        n, d = self.scene.n_particles, self.dimension
        rows = np.arange(self.n_free_dof)
        shapes = np.zeros((d * n, phi.shape[1]), dtype=np.float32)
        shapes[(rows % d) * n + self.free_particles[rows // d]] = phi
        return shapes

    def write_movement(self, out: np.ndarray, shapes: np.ndarray, q: np.ndarray,
                       t: float) -> None:
        """
        Write each particle's movement from rest, ``u + p``, into ``out`` (a translating clamp).

        ``out``: (3, n) float32, C-contiguous, one row per world axis; ``shapes`` from
        :meth:`frame_shapes`; ``q``: float32 coordinates. The rows of axes the scene does not
        move are zero.
        """
        n = self.scene.n_particles
        for k, axis in enumerate(self.axes):  # one product per axis, straight into its row
            np.matmul(shapes[k * n:(k + 1) * n], q, out=out[axis])
        for axis in {0, 1, 2}.difference(self.axes):
            out[axis] = 0.0
        for axis, offset in zip(self.axes, self.anchor_offset(t)):
            if offset:
                out[axis] += np.float32(offset)

    def world_velocity(self, u: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """
        Return the free-DOF velocity in the world (flat).

        Free-DOF velocity in the world (flat) from displacement ``u`` and velocity ``v`` in the
        clamp's frame: ``R v + R' (X + u) + b'``.
        """
        frame = self.frame(t)
        d = self.dimension
        y = self.rest[self.free_particles] + u.reshape(-1, d)
        return (v.reshape(-1, d) @ frame.rotation.T + frame.point_velocity(y)).ravel()

    def positions3(self, x: np.ndarray) -> np.ndarray:
        """(n, 3) positions from (n, d) working positions (axes that do not move stay at rest)."""
        out = np.array(self.scene.rest_positions, dtype=float)
        out[:, self.axes] = x
        return out

    # -- forces --------------------------------------------------------------------------------
    def spring_vectors(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        delta = x[self._j] - x[self._i]
        length = np.sqrt(np.einsum('ed,ed->e', delta, delta))
        return delta, length

    @functools.cached_property
    def physical_forces(self) -> ExactForces:
        """Force on the free DOF in physical coordinates (no modal projection)."""
        return ExactForces(self, None)

    def free_force(self, u: np.ndarray, t: float) -> np.ndarray:
        """Total force on the free DOF (springs, eq. 20, plus gravity) for displacement ``u``."""
        return self.physical_forces(u, t)

    def spring_reach(self, u: np.ndarray) -> float:
        """
        Return how far displacements move springs' ends apart, as a share of their length.

        ``u``: free-DOF displacements in the clamp's frame (n_free_dof,) or one per column
        (n_free_dof, K); the largest ``|u_j - u_i| / l`` over springs and columns (stretch and
        turn alike: a small-displacement model holds only well below 1).
        """
        moved = self.spring_difference @ u.reshape(self.n_free_dof, -1)
        moved = moved.reshape(self.dimension, self._l.size, -1)
        reach = np.sqrt(np.einsum('aek,aek->ek', moved, moved)) * self._inv_l[:, None]
        return float(reach.max(initial=0.0))

    def max_strain(self, x: np.ndarray) -> float:
        """Largest relative spring elongation or compression ``|L - l| / l``."""
        _, length = self.spring_vectors(x)
        return float(np.max(np.abs(length - self._l) * self._inv_l))

    def energy(self, x: np.ndarray, v: np.ndarray) -> dict[str, float]:
        """
        Kinetic, spring (with the bending's) and gravity energy of the free particles.

        ``x``: (n, d) positions; ``v``: free-DOF velocity in the inertial frame (relative
        velocity plus the base velocity).
        """
        _, length = self.spring_vectors(x)
        kinetic = 0.5 * float(np.dot(self.mass_dof * v, v))
        spring = float(np.sum(self.law.energy(length)))
        if self._bending_matrix is not None:   # the bending's energy counts as the springs'
            spring += 0.5 * float(x.ravel() @ (self._bending_matrix @ x.ravel()))
        xf = x[self.free_particles].ravel()
        gravity = -float(np.dot(self.gravity_force, xf))
        return {'kinetic': kinetic, 'spring': spring, 'gravity': gravity,
                'total': kinetic + spring + gravity}

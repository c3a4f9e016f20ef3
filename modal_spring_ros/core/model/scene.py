"""
Scene data: particles, springs, fixed particles, loads and damping of a validated scene.

A :class:`Scene` is what every other part of the engine works from. It is built and checked by
:mod:`modal_spring_ros.scenes` (YAML schema, lattices, built-in scenes); this module only holds
the data and what follows from it alone (degrees of freedom, surface triangles); the scene
file format, read and written, is :mod:`modal_spring_ros.scenes`'.
"""
from __future__ import annotations

import dataclasses

from modal_spring_ros.core.laws import DEFAULT_LAW
from modal_spring_ros.core.model.bending import Bending
from modal_spring_ros.core.model.colliders import Contact
from modal_spring_ros.core.motion.anchor_motion import AnchorMotion
import numpy as np


class SceneError(ValueError):
    """An invalid scene: the message names the source, the field and the problem."""


@dataclasses.dataclass(frozen=True)
class Damping:
    """
    Damping of a scene: the paper's modal ratio ``h`` and/or Rayleigh ``alpha M + beta K``.

    Modal damping of mode ``i`` is ``C_i = 2 h omega_i + alpha + beta omega_i**2`` (with
    mass-normalised modes).
    """

    ratio: float = 0.0
    rayleigh_alpha: float = 0.0
    rayleigh_beta: float = 0.0

    def modal_coefficients(self, omega: np.ndarray) -> np.ndarray:
        """``C_i`` for circular frequencies ``omega`` (rad/s)."""
        omega = np.asarray(omega, dtype=float)
        return 2.0 * self.ratio * omega + self.rayleigh_alpha + self.rayleigh_beta * omega**2

    @property
    def is_zero(self) -> bool:
        return self.ratio == 0.0 and self.rayleigh_alpha == 0.0 and self.rayleigh_beta == 0.0


@dataclasses.dataclass(frozen=True, eq=False)
class Scene:
    """
    A validated mass-spring scene. Arrays are read-only.

    :ivar name: scene name (file stem for scene files).
    :ivar dimension: 1 (motion along ``axis`` only, the paper's chain), 2 (motion in a plane,
        by default the vertical x-z plane of a z-up world; y stays at rest) or 3.
    :ivar axes: the world axes that move (0 = x, 1 = y, 2 = z), ``dimension`` of them.
    :ivar rest_positions: (n, 3) particle positions the motion is measured from and the modes
        are taken about: at rest (springs at their rest length), or the loaded shape (see
        ``unloaded_positions``).
    :ivar mass: (n,) particle masses, kg.
    :ivar springs: (E, 2) particle index pairs, i < j.
    :ivar stiffness: (E,) spring stiffness, N/m.
    :ivar rest_length: (E,) spring rest length, m (distance at rest).
    :ivar fixed: (n,) bool, particles that follow the prescribed anchor motion.
    :ivar gravity: (3,) gravitational acceleration, m/s^2.
    :ivar damping: the scene's damping.
    :ivar anchor_motion: prescribed motion of the fixed particles.
    :ivar default_dt: suggested time step, s (None: chosen from the modes).
    :ivar default_duration: suggested run length, s.
    :ivar description: free text.
    :ivar unloaded_positions: (n, 3) the shape as built (every spring at its rest length) when
        ``rest_positions`` is the loaded shape (the static equilibrium under gravity and the
        clamp, :mod:`~modal_spring_ros.core.model.loaded_shape`); None when they are the same.
    :ivar triangles: (T, 3) particle triangles of the object's surface (a mesh's own), or None
        (a lattice sheet's are found from its springs, :meth:`surface_triangles`).
    :ivar contact: the colliders the object touches and the friction
        (:mod:`~modal_spring_ros.core.model.colliders`), or None.
    :ivar bending: the quadratic bending of a surface flat as built
        (:mod:`~modal_spring_ros.core.model.bending`), or None.
    :ivar spring_law: the springs' law, by its name in
        :data:`~modal_spring_ros.core.laws.SPRING_LAWS` (the paper's linear spring by default).
    """

    name: str
    dimension: int
    axes: tuple[int, ...]
    rest_positions: np.ndarray
    mass: np.ndarray
    springs: np.ndarray
    stiffness: np.ndarray
    rest_length: np.ndarray
    fixed: np.ndarray
    gravity: np.ndarray
    damping: Damping = Damping()
    anchor_motion: AnchorMotion = AnchorMotion(())
    default_dt: float | None = None
    default_duration: float = 5.0
    description: str = ''
    unloaded_positions: np.ndarray | None = None
    triangles: np.ndarray | None = None
    bending: Bending | None = None
    contact: Contact | None = None
    spring_law: str = DEFAULT_LAW

    @property
    def n_particles(self) -> int:
        return int(self.rest_positions.shape[0])

    @property
    def n_springs(self) -> int:
        return int(self.springs.shape[0])

    @property
    def loaded(self) -> bool:
        """Tell whether the motion is about the loaded shape (springs stretched at rest)."""
        return self.unloaded_positions is not None

    @property
    def n_free_dof(self) -> int:
        return int((~self.fixed).sum()) * self.dimension

    def surface_triangles(self) -> np.ndarray:
        """
        Return the (T, 3) particle triangles of the surface, empty when it has none.

        A mesh's own triangles; a 2D lattice sheet is a surface (two triangles per cell, taken
        from its diagonal springs' cells), a 3D lattice block's skin is its six faces (two
        triangles per face cell, turned outward); scenes without that structure return an empty
        array.
        """
        if self.triangles is not None:
            return self.triangles
        if self.dimension == 3:
            return _block_skin(self)
        return _lattice_triangles(self)


def _lattice_grid(scene: Scene, axes) -> np.ndarray | None:
    """
    Return each lattice node's particle, indexed along ``axes`` in order, or None.

    None unless the particles fill a full lattice on those axes (at least two nodes along each).
    """
    coords = [np.round(scene.rest_positions[:, a], 12) for a in axes]
    nodes = [np.unique(c) for c in coords]
    if np.prod([n.size for n in nodes]) != scene.n_particles or min(n.size for n in nodes) < 2:
        return None
    grid = np.full([n.size for n in nodes], -1, dtype=np.int64)
    grid[tuple(np.searchsorted(n, c) for n, c in zip(nodes, coords))] = np.arange(
        scene.n_particles)
    return grid


def _block_skin(scene: Scene) -> np.ndarray:
    """Return the outward triangles of a full 3D lattice's six faces (a particle at each node)."""
    grid = _lattice_grid(scene, (0, 1, 2))
    if grid is None:
        return np.empty((0, 3), dtype=np.int64)
    faces = []
    for axis in range(3):
        for side, outward in ((0, -1.0), (-1, 1.0)):
            face = np.take(grid, side, axis=axis)   # the other two axes, in order
            a, b = face[:-1, :-1].ravel(), face[1:, :-1].ravel()
            c, d = face[1:, 1:].ravel(), face[:-1, 1:].ravel()
            # (a, b, c) turns about +e_axis for axes 0 and 2, about -e_axis for axis 1
            if outward * (1.0 if axis != 1 else -1.0) < 0:
                b, d = d, b
            faces += [np.stack([a, b, c], 1), np.stack([a, c, d], 1)]
    return np.concatenate(faces)


def _lattice_triangles(scene: Scene) -> np.ndarray:
    """Two triangles per square cell of a planar lattice whose four edges are springs."""
    grid = None if scene.dimension != 2 else _lattice_grid(scene, scene.axes[::-1])  # [up, across]
    if grid is None:
        return np.empty((0, 3), dtype=np.int64)
    a = grid[:-1, :-1].ravel()
    b = grid[:-1, 1:].ravel()
    c = grid[1:, 1:].ravel()
    d = grid[1:, :-1].ravel()
    edges = {tuple(p) for p in scene.springs.tolist()}

    def has(u, v):
        return np.array([(min(p, q), max(p, q)) in edges for p, q in zip(u, v)], dtype=bool)

    cell = has(a, b) & has(b, c) & has(c, d) & has(d, a)
    tris = np.concatenate([np.stack([a, b, c], 1)[cell], np.stack([a, c, d], 1)[cell]])
    return tris

"""
What the object can touch: solid shapes fixed in the world, and the friction between them and it.

A scene's ``contact`` (:class:`Contact`) lists colliders, each a solid: a plane (the half-space
below it: a table, the ground), a sphere, an axis-aligned box, a capsule (a segment with a
radius: a finger) and a cylinder (a centre, an axis, a radius and a half length). Each gives,
for world points, the signed distance to its surface (negative inside) and the outward normal
of the nearest surface point: a point inside is pushed out the nearest way, all vectorised over
the points. The forces that keep the particles out are a load
(:mod:`~modal_spring_ros.core.loads.contact`); here is the geometry only.

A collider is fixed in the world or attached to a frame (``Contact.frames``): then its shape is
given in the frame's coordinates and the frame's :class:`Pose` (a robot link's, from TF) says
where it is. A new shape is one subclass with :meth:`Collider.distance` and one line in
:data:`SHAPES`.
"""
from __future__ import annotations

import abc
import dataclasses
from typing import ClassVar

from modal_spring_ros.core.motion.clamp_follower import rotation_matrix, rotation_vector
import numpy as np

#: a point this close to a shape's centre (or axis) takes a fixed outward direction
TINY = 1e-12


def _unit(v: np.ndarray) -> np.ndarray:
    length = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.divide(v, length, out=np.zeros_like(v), where=length > TINY)


def _away(v: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    """Return ``v`` normalised, ``fallback`` where it vanishes."""
    length = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.where(length > TINY, v / np.maximum(length, TINY), fallback)


class Collider(abc.ABC):
    """A solid shape fixed in the world."""

    shape: ClassVar[str]

    @abc.abstractmethod
    def distance(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return signed distances (k,), negative inside, and outward normals (k, 3) of points."""

    @abc.abstractmethod
    def thickness(self) -> float:
        """Return the solid's smallest extent through it, m (inf: a half-space)."""

    def to_dict(self) -> dict:
        """Return the collider as the scene file writes it."""
        out = {'shape': self.shape}
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            out[field.name] = np.asarray(value).tolist() if isinstance(
                value, np.ndarray) else float(value)
        return out


@dataclasses.dataclass(frozen=True, eq=False)
class Plane(Collider):
    """The half-space below the plane through ``point`` with outward ``normal``."""

    shape: ClassVar[str] = 'plane'
    point: np.ndarray
    normal: np.ndarray

    def distance(self, p):
        n = self.normal / np.linalg.norm(self.normal)
        return (p - self.point) @ n, np.broadcast_to(n, p.shape)

    def thickness(self) -> float:
        return np.inf


@dataclasses.dataclass(frozen=True, eq=False)
class Sphere(Collider):
    shape: ClassVar[str] = 'sphere'
    center: np.ndarray
    radius: float

    def distance(self, p):
        r = p - self.center
        return np.linalg.norm(r, axis=1) - self.radius, _away(r, np.array([0.0, 0.0, 1.0]))

    def thickness(self) -> float:
        return 2.0 * self.radius


@dataclasses.dataclass(frozen=True, eq=False)
class Box(Collider):
    """An axis-aligned box: ``center`` and ``half_extents``."""

    shape: ClassVar[str] = 'box'
    center: np.ndarray
    half_extents: np.ndarray

    def distance(self, p):
        r = p - self.center
        q = np.abs(r) - self.half_extents
        side = np.where(r < 0.0, -1.0, 1.0)
        outside = np.maximum(q, 0.0)
        out_d = np.linalg.norm(outside, axis=1)
        axis = np.argmax(q, axis=1)
        in_n = np.zeros_like(p)
        in_n[np.arange(len(p)), axis] = side[np.arange(len(p)), axis]
        is_out = out_d > 0.0
        d = np.where(is_out, out_d, q.max(axis=1))
        n = np.where(is_out[:, None], _unit(side * outside), in_n)
        return d, n

    def thickness(self) -> float:
        return 2.0 * float(np.min(self.half_extents))


@dataclasses.dataclass(frozen=True, eq=False)
class Capsule(Collider):
    """The points within ``radius`` of the segment ``a``-``b``."""

    shape: ClassVar[str] = 'capsule'
    a: np.ndarray
    b: np.ndarray
    radius: float

    def distance(self, p):
        ab = self.b - self.a
        s = np.clip((p - self.a) @ ab / max(float(ab @ ab), TINY), 0.0, 1.0)
        r = p - (self.a + s[:, None] * ab)
        fallback = _unit(np.cross(ab, [0.0, 0.0, 1.0]) if abs(ab[2]) < np.linalg.norm(ab)
                         else np.array([1.0, 0.0, 0.0]))
        return np.linalg.norm(r, axis=1) - self.radius, _away(r, fallback)

    def thickness(self) -> float:
        return 2.0 * self.radius


@dataclasses.dataclass(frozen=True, eq=False)
class Cylinder(Collider):
    """A solid cylinder: ``center``, unit ``axis``, ``radius`` and ``half_length``."""

    shape: ClassVar[str] = 'cylinder'
    center: np.ndarray
    axis: np.ndarray
    radius: float
    half_length: float

    def distance(self, p):
        a = self.axis / np.linalg.norm(self.axis)
        r = p - self.center
        h = r @ a
        radial = r - h[:, None] * a
        rho = np.linalg.norm(radial, axis=1)
        dr, dh = rho - self.radius, np.abs(h) - self.half_length
        fallback = _unit(np.cross(a, [0.0, 0.0, 1.0]) if abs(a[2]) < 1.0 - 1e-9
                         else np.array([1.0, 0.0, 0.0]))
        out_r = _away(radial, fallback)
        out_h = np.where(h[:, None] < 0.0, -a, a)
        both = (dr > 0.0) & (dh > 0.0)
        d = np.where(both, np.hypot(np.maximum(dr, 0.0), np.maximum(dh, 0.0)),
                     np.maximum(dr, dh))
        n = np.where((dr > dh)[:, None], out_r, out_h)
        n = np.where(both[:, None], _unit(dr[:, None] * out_r + dh[:, None] * out_h), n)
        return d, n

    def thickness(self) -> float:
        return 2.0 * min(self.radius, self.half_length)


#: the shapes by the name a scene file gives them
SHAPES: dict[str, type[Collider]] = {c.shape: c for c in (Plane, Sphere, Box, Capsule,
                                                          Cylinder)}


@dataclasses.dataclass(frozen=True, eq=False)
class Contact:
    """
    A scene's colliders and the friction between them and the object.

    ``static_friction`` holds a particle (Coulomb: the tangential force up to it times the
    normal force), ``sliding_friction`` acts on a particle that slides. ``frames``: the frame
    each collider is attached to ('' for the world, the default): an attached collider's shape
    is given in its frame's coordinates, and it is where that frame's pose puts it
    (:class:`Pose`), once a pose is known (a robot link, from TF).
    """

    colliders: tuple[Collider, ...]
    static_friction: float = 0.0
    sliding_friction: float = 0.0
    frames: tuple[str, ...] = ()

    def frame(self, c: int) -> str:
        """Return the frame collider ``c`` is attached to ('': the world)."""
        return self.frames[c] if c < len(self.frames) else ''

    @property
    def attached(self) -> tuple[str, ...]:
        """Return the frames colliders are attached to, each once, in order."""
        return tuple(dict.fromkeys(f for f in self.frames if f))

    def to_dict(self) -> dict:
        """Return the ``contact`` field as the scene file writes it."""
        friction = (self.static_friction if self.static_friction == self.sliding_friction
                    else {'static': self.static_friction, 'sliding': self.sliding_friction})
        return {'friction': friction, 'colliders': [
            {**c.to_dict(), **({'frame': self.frame(i)} if self.frame(i) else {})}
            for i, c in enumerate(self.colliders)]}


@dataclasses.dataclass(frozen=True, eq=False)
class Pose:
    """
    Where a frame is in the world: ``x_world = rotation @ x_frame + translation``.

    A collider attached to the frame measures world points in the frame's coordinates and
    turns its normals back into the world's.
    """

    rotation: np.ndarray        # (3, 3)
    translation: np.ndarray     # (3,)

    @classmethod
    def of(cls, translation, quaternion) -> 'Pose':
        """Return the pose of a translation and a unit quaternion (x, y, z, w)."""
        rotation = rotation_matrix(rotation_vector(np.asarray(quaternion, dtype=float)))
        return cls(rotation, np.asarray(translation, dtype=float))

    def into_frame(self, points: np.ndarray) -> np.ndarray:
        """Return world ``points`` (k, 3) in the frame's coordinates."""
        return (points - self.translation) @ self.rotation

    def to_world(self, vectors: np.ndarray) -> np.ndarray:
        """Return directions (k, 3) given in the frame's coordinates in the world's."""
        return vectors @ self.rotation.T

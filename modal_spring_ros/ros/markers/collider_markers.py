"""
The scene's colliders as RViz draws them: one ``visualization_msgs/MarkerArray``.

What the object touches (:mod:`~modal_spring_ros.core.model.colliders`) drawn with RViz's own
primitives, grey and half transparent, in the node's ``frame_id``: a plane as a thin square of
``plane_size`` about its point, turned to its normal; a sphere; an axis-aligned box; a cylinder
turned to its axis; a capsule as a cylinder between its end points and a sphere at each. The node
publishes it once, latched (transient local, as ``robot_description`` is), on ``colliders``: a
viewer that comes later has it, and the object's ``mesh`` marker is drawn on top of it.
"""
from __future__ import annotations

from typing import Callable

from geometry_msgs.msg import Point, Pose, Quaternion, Vector3
from modal_spring_ros.core.model.colliders import (Box, Capsule, Collider, Contact, Cylinder,
                                                   Plane, Sphere)
import numpy as np
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker, MarkerArray

#: how the colliders look: grey, half transparent
COLOUR = ColorRGBA(r=0.6, g=0.6, b=0.6, a=0.5)
#: a plane's drawn thickness, m
PLANE_THICKNESS = 0.002
#: the markers' namespace
NAMESPACE = 'modal_spring_colliders'


def z_to(direction: np.ndarray) -> Quaternion:
    """Return the shortest turn of the z axis onto ``direction`` (RViz draws along z)."""
    d = np.asarray(direction, dtype=float)
    d = d / np.linalg.norm(d)
    if d[2] < -1.0 + 1e-12:                       # opposite: half a turn about x
        return Quaternion(x=1.0, y=0.0, z=0.0, w=0.0)
    q = np.array([-d[1], d[0], 0.0, 1.0 + d[2]])   # (z x d, 1 + z . d), normalised
    q /= np.linalg.norm(q)
    return Quaternion(x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3]))


def _marker(kind: int, centre, scale, turn: Quaternion | None = None) -> Marker:
    c = [float(v) for v in centre]
    return Marker(type=kind, action=Marker.ADD, color=COLOUR,
                  pose=Pose(position=Point(x=c[0], y=c[1], z=c[2]),
                            orientation=turn or Quaternion(w=1.0)),
                  scale=Vector3(x=float(scale[0]), y=float(scale[1]), z=float(scale[2])))


def _plane(c: Plane, size: float) -> list[Marker]:
    return [_marker(Marker.CUBE, c.point, (size, size, PLANE_THICKNESS), z_to(c.normal))]


def _sphere(c: Sphere, _: float) -> list[Marker]:
    return [_marker(Marker.SPHERE, c.center, [2.0 * c.radius] * 3)]


def _box(c: Box, _: float) -> list[Marker]:
    return [_marker(Marker.CUBE, c.center, 2.0 * np.asarray(c.half_extents, dtype=float))]


def _cylinder(c: Cylinder, _: float) -> list[Marker]:
    return [_marker(Marker.CYLINDER, c.center, (2.0 * c.radius, 2.0 * c.radius,
                                                2.0 * c.half_length), z_to(c.axis))]


def _capsule(c: Capsule, _: float) -> list[Marker]:
    a, b = np.asarray(c.a, dtype=float), np.asarray(c.b, dtype=float)
    ends = [_marker(Marker.SPHERE, end, [2.0 * c.radius] * 3) for end in (a, b)]
    length = float(np.linalg.norm(b - a))
    if length == 0.0:
        return ends[:1]
    return [_marker(Marker.CYLINDER, 0.5 * (a + b), (2.0 * c.radius, 2.0 * c.radius, length),
                    z_to(b - a)), *ends]


#: each shape's drawing, by its class (a new shape adds one)
DRAWINGS: dict[type[Collider], Callable[[Collider, float], list[Marker]]] = {
    Plane: _plane, Sphere: _sphere, Box: _box, Cylinder: _cylinder, Capsule: _capsule}


def collider_markers(contact: Contact, header: Header, plane_size: float) -> MarkerArray:
    """
    Return the markers of ``contact``'s colliders (ids from 0, in ``header``'s frame).

    A collider attached to a frame is drawn in that frame (RViz places it through TF, as it
    moves), the others in ``header``'s.
    """
    markers = []
    for k, collider in enumerate(contact.colliders):
        frame = contact.frame(k)
        own = Header(stamp=header.stamp, frame_id=frame) if frame else header
        for m in DRAWINGS[type(collider)](collider, plane_size):
            m.header = own
            markers.append(m)
    for i, m in enumerate(markers):
        m.ns, m.id = NAMESPACE, i
    return MarkerArray(markers=markers)

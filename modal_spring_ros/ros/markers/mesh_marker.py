"""
The object as RViz draws it: one ``visualization_msgs/Marker`` of its surface (or its springs).

Coloured blue (at rest) to red (most displaced), published on ``mesh`` while someone subscribes
to it (:mod:`~modal_spring_ros.ros.stream.outputs`).
"""
from __future__ import annotations

from geometry_msgs.msg import Point
from modal_spring_ros.bags.messages.pointcloud import distance_from_rest
from modal_spring_ros.core.model.scene import Scene
import numpy as np
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker


def mesh_marker(positions: np.ndarray, rest: np.ndarray, cells: np.ndarray, header: Header,
                width: float = 0.0) -> Marker:
    """
    Return the object as RViz draws it, coloured blue (at rest) to red (most displaced).

    ``cells`` (T, 3): a TRIANGLE_LIST of its surface; (E, 2): a LINE_LIST of its springs,
    ``width`` m wide (an object with no surface, such as a chain).
    """
    corners = positions[cells.ravel()]
    disp = distance_from_rest(corners, rest[cells.ravel()])
    level = np.clip(disp / max(float(disp.max()), 1e-12), 0.0, 1.0)
    lines = cells.shape[1] == 2
    m = Marker(header=header, ns='modal_spring', id=0,
               type=Marker.LINE_LIST if lines else Marker.TRIANGLE_LIST, action=Marker.ADD)
    m.pose.orientation.w = 1.0
    m.scale.x = m.scale.y = m.scale.z = 1.0
    if lines:
        m.scale.x = width
    m.points = [Point(x=x, y=y, z=z) for x, y, z in corners.tolist()]
    m.colors = [ColorRGBA(r=c, g=0.2, b=1.0 - c, a=1.0) for c in level.tolist()]
    return m


def marker_cells(scene: Scene) -> tuple[np.ndarray, float]:
    """Return what the mesh marker draws: the surface's triangles, else the springs and a width."""
    triangles = scene.surface_triangles()
    if triangles.size:
        return triangles, 0.0
    return scene.springs, 0.1 * float(np.median(scene.rest_length))

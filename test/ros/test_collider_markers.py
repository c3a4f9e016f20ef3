"""The scene's colliders as RViz draws them (markers), and latched on the node's ``colliders``."""
from __future__ import annotations

from helpers import variant
from modal_spring_ros.core.model.colliders import (Box, Capsule, Contact, Cylinder, Plane,
                                                   Sphere)
from modal_spring_ros.ros.markers.collider_markers import collider_markers, z_to
from modal_spring_ros.scenes.files.writing import scene_to_dict
import numpy as np
import pytest
from rclpy.qos import DurabilityPolicy, QoSProfile
from ros_harness import Client, running_node, wait_for
from std_msgs.msg import Header
from visualization_msgs.msg import Marker, MarkerArray
import yaml

pytestmark = pytest.mark.ros


def turned_z(q) -> np.ndarray:
    """Return the z axis turned by the quaternion ``q`` (the third column of its matrix)."""
    x, y, z, w = q.x, q.y, q.z, q.w
    return np.array([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])


@pytest.mark.parametrize('direction', [(0, 0, 1), (0, 0, -1), (1, 0, 0), (0, -3, 0),
                                       (1, 2, -2), (1e-9, 0, -1)])
def test_the_z_axis_is_turned_onto_any_direction(direction):
    d = np.asarray(direction, dtype=float)
    q = z_to(d)
    assert q.x ** 2 + q.y ** 2 + q.z ** 2 + q.w ** 2 == pytest.approx(1.0)
    np.testing.assert_allclose(turned_z(q), d / np.linalg.norm(d), atol=1e-6)


def test_each_shape_is_drawn_where_and_as_large_as_it_is():
    contact = Contact((
        Plane(np.array([0.0, 0.0, -1.0]), np.array([0.0, 1.0, 1.0])),
        Sphere(np.array([1.0, 2.0, 3.0]), 0.25),
        Box(np.array([0.5, 0.0, 0.0]), np.array([0.1, 0.2, 0.3])),
        Cylinder(np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0]), 0.05, 0.4),
        Capsule(np.array([0.0, 0.0, 0.0]), np.array([0.0, 0.0, 0.6]), 0.02)), 0.4, 0.3)
    markers = collider_markers(contact, Header(frame_id='table'), plane_size=3.0).markers
    assert [m.id for m in markers] == list(range(7))
    assert {m.header.frame_id for m in markers} == {'table'}
    assert [m.type for m in markers] == [Marker.CUBE, Marker.SPHERE, Marker.CUBE,
                                         Marker.CYLINDER, Marker.CYLINDER, Marker.SPHERE,
                                         Marker.SPHERE]
    plane, sphere, box, cylinder, capsule, end_a, end_b = markers

    def centre(m):
        return [m.pose.position.x, m.pose.position.y, m.pose.position.z]

    def scale(m):
        return [m.scale.x, m.scale.y, m.scale.z]
    assert centre(plane) == [0.0, 0.0, -1.0] and scale(plane)[:2] == [3.0, 3.0]
    np.testing.assert_allclose(turned_z(plane.pose.orientation), [0, 0.5 ** 0.5, 0.5 ** 0.5])
    assert centre(sphere) == [1.0, 2.0, 3.0] and scale(sphere) == [0.5, 0.5, 0.5]
    assert scale(box) == pytest.approx([0.2, 0.4, 0.6]) and box.pose.orientation.w == 1.0
    assert scale(cylinder) == pytest.approx([0.1, 0.1, 0.8])
    np.testing.assert_allclose(turned_z(cylinder.pose.orientation), [1, 0, 0], atol=1e-12)
    assert centre(capsule) == pytest.approx([0, 0, 0.3])
    assert scale(capsule) == pytest.approx([0.04, 0.04, 0.6])
    assert centre(end_a) == [0, 0, 0] and centre(end_b) == pytest.approx([0, 0, 0.6])
    assert all(0.0 < m.color.a < 1.0 for m in markers)


def test_a_collider_on_a_frame_is_drawn_in_that_frame():
    """A collider's marker is in its frame: RViz places it through TF as the frame moves."""
    contact = Contact((Sphere(np.array([0.0, 0.0, 0.1]), 0.05),
                       Plane(np.array([0.0, 0.0, -1.0]), np.array([0.0, 0.0, 1.0]))),
                      frames=('tool0', ''))
    sphere, plane = collider_markers(contact, Header(frame_id='world'), plane_size=2.0).markers
    assert (sphere.header.frame_id, plane.header.frame_id) == ('tool0', 'world')
    assert [sphere.pose.position.z, sphere.id, plane.id] == [0.1, 0, 1]


def test_the_node_latches_its_scene_s_colliders_for_a_viewer_that_comes_later(tmp_path):
    data = scene_to_dict(variant('sheet_10x10'))
    data['contact'] = {'friction': 0.5, 'colliders': [
        {'shape': 'plane', 'point': [0.0, 0.0, -1.5], 'normal': [0.0, 0.0, 1.0]},
        {'shape': 'sphere', 'center': [0.45, 0.0, -1.2], 'radius': 0.1}]}
    scene_file = tmp_path / 'table.yaml'
    scene_file.write_text(yaml.safe_dump(data))
    with running_node(f'scene:={scene_file}', 'frame_id:=bench', namespace='touch') as node:
        with Client('touch_client') as client:
            assert wait_for(lambda: 'streaming' in node.stderr(), 60)
            # a viewer that subscribes after the node published: latched, it has the colliders
            got = []
            client.node.create_subscription(
                MarkerArray, '/touch/colliders', got.append,
                QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
            assert wait_for(lambda: got, 20)
    markers = got[-1].markers
    assert [m.type for m in markers] == [Marker.CUBE, Marker.SPHERE]
    assert {m.header.frame_id for m in markers} == {'bench'}
    assert markers[1].scale.x == pytest.approx(0.2)

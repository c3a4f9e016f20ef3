"""The TF tree the node keeps: composition through common ancestors, and what it refuses."""
from __future__ import annotations

import math

from modal_spring_ros.ros.frames.frame_tree import FrameTree, quaternion_from_matrix, Transform
import numpy as np
import pytest


def turn(axis: str, degrees: float) -> np.ndarray:
    """Quaternion ``(x, y, z, w)`` of a turn about a world axis."""
    a = math.radians(degrees) / 2
    q = np.zeros(4)
    q['xyz'.index(axis)], q[3] = math.sin(a), math.cos(a)
    return q


def matrix(axis: str, degrees: float) -> np.ndarray:
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    i = 'xyz'.index(axis)
    j, k = (i + 1) % 3, (i + 2) % 3
    out = np.eye(3)
    out[j, j] = out[k, k] = c
    out[k, j], out[j, k] = s, -s
    return out


def test_a_transform_turns_then_moves_and_its_inverse_undoes_it():
    t = Transform(np.array([1.0, 2.0, 3.0]), turn('z', 90.0))
    np.testing.assert_allclose(t.apply(np.array([1.0, 0.0, 0.0])), [1.0, 3.0, 3.0], atol=1e-12)
    np.testing.assert_allclose(t.matrix(), matrix('z', 90.0), atol=1e-12)
    points = np.random.default_rng(1).normal(size=(5, 3))
    np.testing.assert_allclose(t.inverse().apply(t.apply(points)), points, atol=1e-12)


@pytest.mark.parametrize('axis,degrees', [('x', 30.0), ('y', -170.0), ('z', 180.0),
                                          ('x', 0.0)])
def test_quaternion_from_matrix_gives_back_the_turn(axis, degrees):
    q = quaternion_from_matrix(matrix(axis, degrees))
    np.testing.assert_allclose(Transform(np.zeros(3), q).matrix(), matrix(axis, degrees),
                               atol=1e-12)
    assert q[3] >= 0.0 and math.isclose(float(np.linalg.norm(q)), 1.0)


def test_a_lookup_composes_through_the_common_ancestor():
    # world -> base (1 m up x, turned 90 about z) -> gripper (0.5 m along the base's x);
    # world -> camera (2 m along y)
    tree = FrameTree()
    assert tree.set_link('world', 'base', (1.0, 0.0, 0.0), turn('z', 90.0)) is None
    assert tree.set_link('base', 'gripper', (0.5, 0.0, 0.0), turn('y', 0.0)) is None
    assert tree.set_link('/world', 'camera', (0.0, 2.0, 0.0), (0.0, 0.0, 0.0, 1.0)) is None
    gripper_in_world = tree.lookup('world', 'gripper')
    np.testing.assert_allclose(gripper_in_world.translation, [1.0, 0.5, 0.0], atol=1e-12)
    # a point at the camera's origin, seen from the gripper: world (0, 2, 0)
    camera_in_gripper = tree.lookup('gripper', 'camera')
    np.testing.assert_allclose(gripper_in_world.apply(camera_in_gripper.apply(np.zeros(3))),
                               [0.0, 2.0, 0.0], atol=1e-12)
    # the other way round is the inverse
    back = tree.lookup('camera', 'gripper')
    np.testing.assert_allclose(back.then(camera_in_gripper).apply(np.ones(3)), np.ones(3),
                               atol=1e-12)
    assert np.allclose(tree.lookup('base', 'base').translation, 0.0)


def test_the_latest_transform_of_a_link_is_used():
    tree = FrameTree()
    tree.set_link('world', 'gripper', (0.0, 0.0, 0.0), turn('z', 0.0))
    tree.set_link('world', 'gripper', (0.0, 0.0, 1.0), turn('z', 0.0))
    np.testing.assert_allclose(tree.lookup('world', 'gripper').translation, [0.0, 0.0, 1.0])


@pytest.mark.parametrize('parent,child,translation,rotation,reason', [
    ('world', 'world', (0, 0, 0), (0, 0, 0, 1), 'its own parent'),
    ('', 'a', (0, 0, 0), (0, 0, 0, 1), 'empty frame name'),
    ('world', 'a', (math.nan, 0, 0), (0, 0, 0, 1), 'non-finite'),
    ('world', 'a', (0, 0, 0), (0, 0, math.inf, 1), 'non-finite'),
    ('world', 'a', (0, 0, 0), (0, 0, 0, 2), 'not a unit quaternion'),
    ('child', 'world', (0, 0, 0), (0, 0, 0, 1), 'close a loop'),
])
def test_bad_transforms_are_refused_with_their_reason_and_change_nothing(
        parent, child, translation, rotation, reason):
    tree = FrameTree()
    tree.set_link('world', 'child', (1.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
    why = tree.set_link(parent, child, translation, rotation)
    assert why is not None and reason in why
    assert len(tree) == 1
    np.testing.assert_allclose(tree.lookup('world', 'child').translation, [1.0, 0.0, 0.0])


def test_unknown_and_unconnected_frames_are_named():
    tree = FrameTree(max_frames=2)
    tree.set_link('world', 'a', (0, 0, 0), (0, 0, 0, 1))
    tree.set_link('map', 'b', (0, 0, 0), (0, 0, 0, 1))
    assert "'gripper' is not in the TF tree" in tree.lookup('world', 'gripper')
    assert 'not connected' in tree.lookup('a', 'b')
    # a flood of new names is not kept
    assert 'more than 2 frames' in tree.set_link('world', 'c', (0, 0, 0), (0, 0, 0, 1))
    assert tree.set_link('world', 'a', (1, 0, 0), (0, 0, 0, 1)) is None     # known ones still move

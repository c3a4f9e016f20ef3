"""Clicks, wrenches and collider poses without DDS: where they act, what a capture keeps."""
from __future__ import annotations

import math

from builtin_interfaces.msg import Time
from geometry_msgs.msg import PointStamped, TransformStamped, WrenchStamped
from helpers import variant
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.loads.pull import nearest_free_particle
from modal_spring_ros.ros.frames.frame_tree import Transform
from modal_spring_ros.ros.frames.tf import transform_message
from modal_spring_ros.ros.inputs.input_kinds import (CLICKED_POINT, COLLIDER_MARKER, FRAME_POSE,
                                                     GRASP, recorded_messages, WRENCH, WrenchAt)
from modal_spring_ros.ros.inputs.robot_world import transform_arrays
from modal_spring_ros.ros.parameters import PARAMETERS
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest
from sensor_msgs.msg import JointState
from visualization_msgs.msg import Marker

VALUES = {name: default for name, (default, _) in PARAMETERS.items()}


def wrench(frame_id: str = 'world', force=(1.0, 0.0, 0.0), torque=(0.0, 0.0, 0.0)):
    message = WrenchStamped()
    message.header.frame_id = frame_id
    f, t = message.wrench.force, message.wrench.torque
    f.x, f.y, f.z = (float(v) for v in force)
    t.x, t.y, t.z = (float(v) for v in torque)
    return message


@pytest.fixture
def sim():
    return build_simulation(load_scene('sheet_10x10'), SimulationConfig(max_modes=20))


def test_a_wrench_in_the_nodes_frame_acts_at_its_origin_and_is_kept_as_it_came(sim):
    message = wrench()
    assert WRENCH.refusal(message, VALUES, None) is None
    said = WRENCH.apply(sim, message, VALUES)
    nearest = nearest_free_particle(sim.model, sim.positions(), np.zeros(3))
    assert nearest in sim.wrench.particles and said.startswith('pushing')
    np.testing.assert_allclose(sim.wrench.force, [1.0, 0.0, 0.0])
    assert recorded_messages(WRENCH, message) == [('/wrench', message)]


def test_a_wrench_carried_through_tf_acts_at_its_frames_origin_on_the_nodes_axes(sim):
    # a frame half a turn about z from the world, at the middle particle: +x there is -x here
    middle = sim.positions()[55]
    carried = WRENCH.to_frame(wrench('pusher'), Transform(middle, (0.0, 0.0, 1.0, 0.0)),
                              'world')
    assert isinstance(carried, WrenchAt) and carried.header.frame_id == 'world'
    point, force, _ = carried.arrays()
    np.testing.assert_allclose(point, middle)
    np.testing.assert_allclose(force, [-1.0, 0.0, 0.0], atol=1e-12)
    WRENCH.apply(sim, carried, VALUES)
    assert 55 in sim.wrench.particles
    topics = [topic for topic, _ in recorded_messages(WRENCH, carried)]
    assert topics == ['/wrench_point', '/wrench']


def test_a_zero_wrench_ends_the_push_and_a_non_finite_one_is_refused(sim):
    WRENCH.apply(sim, wrench(), VALUES)
    assert sim.wrench is not None
    assert WRENCH.apply(sim, wrench(force=(0, 0, 0)), VALUES).startswith('wrench ended')
    assert sim.wrench is None
    assert WRENCH.refusal(wrench(torque=(0, np.nan, 0)), VALUES, None) == 'non-finite values'


def click(at) -> PointStamped:
    message = PointStamped()
    message.header.frame_id = 'world'
    message.point.x, message.point.y, message.point.z = (float(v) for v in at)
    return message


def test_clicks_pick_and_place(sim):
    """On the object: grab where it is; then any click takes the held particle there."""
    x = sim.positions()
    said = CLICKED_POINT.apply(sim, click(x[0]), VALUES)
    assert said.startswith('grabbed particle 0') and sim.pull.particle == 0
    np.testing.assert_allclose(sim.pull.target, x[0, sim.model.axes])
    CLICKED_POINT.apply(sim, click(x[55]), VALUES)              # on the object, elsewhere
    assert sim.pull.particle == 0
    np.testing.assert_allclose(sim.pull.target, x[55, sim.model.axes])
    CLICKED_POINT.apply(sim, click(x[0] + [0, 0, -0.5]), VALUES)    # off it: still the held one
    assert sim.pull.particle == 0
    CLICKED_POINT.apply(sim, click(x[0]), VALUES)               # on the held one: grabbed anew
    np.testing.assert_allclose(sim.pull.target, x[0, sim.model.axes])
    sim.start_pull(None)
    said = CLICKED_POINT.apply(sim, click(x[9] + [0.5, 0, 0]), VALUES)   # nothing held, off it
    assert said == 'pulling particle 9'


def finger_scene():
    """``sheet_10x10`` still, with a 5 cm sphere on a ``finger`` frame and a world table."""
    return variant('sheet_10x10', anchor_motion=[], contact={'colliders': [
        {'shape': 'sphere', 'center': [0.0, 0.0, 0.0], 'radius': 0.05, 'frame': 'finger'},
        {'shape': 'plane', 'point': [0.0, 0.0, -2.0], 'normal': [0.0, 0.0, 1.0]}]})


def frame_pose(child: str = 'finger', translation=(0.0, 0.0, 0.0),
               rotation=(0.0, 0.0, 0.0, 1.0), frame_id: str = 'world') -> TransformStamped:
    return transform_message(frame_id, child, Transform(np.array(translation, dtype=float),
                                                        np.array(rotation, dtype=float)), Time())


def test_a_frame_pose_puts_the_colliders_of_its_frame_there_and_bad_ones_are_refused():
    sim = build_simulation(finger_scene(), SimulationConfig(method='full'))
    edge = sim.positions()[40].copy()                 # the left edge, x = 0, z = -0.5
    for k in range(40):                               # from outside into the sheet, 1 mm a step
        message = frame_pose(translation=edge + [-0.07 + 0.001 * k, 0.0, 0.0])
        assert FRAME_POSE.refusal(message, VALUES, None) is None
        assert FRAME_POSE.apply(sim, message, VALUES) == (
            'finger moved: 1 collider or gripper on it')
        sim.step(1)
    assert sim.loads['contact'].touching >= 1
    assert sim.positions()[40, 0] > edge[0] + 0.01    # pushed along +x by the sphere
    assert FRAME_POSE.apply(sim, frame_pose('thumb'), VALUES) == (
        'thumb moved: no collider or closed gripper is on it')
    assert recorded_messages(FRAME_POSE, message) == [('/frame_pose', message)]
    for bad, why in ((frame_pose(translation=(math.nan, 0, 0)), 'non-finite'),
                     (frame_pose(rotation=(0, 0, 0, 2)), 'not a unit quaternion'),
                     (frame_pose(child=''), 'no child_frame_id')):
        assert why in FRAME_POSE.refusal(bad, VALUES, None)


def test_a_frame_pose_in_another_frame_is_carried_into_the_nodes():
    # the robot's base 1 m up along z, a quarter turn about z: the finger 0.1 m along its x
    half = math.sqrt(0.5)
    base = Transform(np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, half, half]))
    carried = FRAME_POSE.to_frame(frame_pose(translation=(0.1, 0.0, 0.0), frame_id='base'),
                                  base, 'world')
    position, quaternion = transform_arrays(carried)
    assert carried.header.frame_id == 'world' and carried.child_frame_id == 'finger'
    np.testing.assert_allclose(position, [0.0, 0.1, 1.0], atol=1e-12)
    np.testing.assert_allclose(quaternion, [0.0, 0.0, half, half], atol=1e-12)


def grasp(**grippers: float) -> JointState:
    return JointState(name=list(grippers), position=[float(p) for p in grippers.values()])


def test_two_grippers_close_on_what_is_within_reach_carry_it_and_let_go():
    """
    Two grippers at the sheet's bottom corners close, lift them 10 cm, and open.

    Each holds the corner particle (within 2 cm of its frame); moved up, the corners follow
    to within the hold's bound; opened, they let go. A gripper with no pose yet, or nothing
    within reach, cannot close, and says why; refused: a name that is no gripper.
    """
    sim = build_simulation(variant('sheet_10x10', anchor_motion=[]),
                           SimulationConfig(method='full'))
    values = dict(VALUES, **{'grasp.frames': 'left, right', 'grasp.reach': 0.02})
    assert 'left cannot close: left has no pose yet' in GRASP.apply(sim, grasp(left=1), values)
    corners = sim.positions()[[0, 9]]
    for frame, corner in zip(('left', 'right'), corners):
        FRAME_POSE.apply(sim, frame_pose(frame, corner), values)
    assert GRASP.refusal(grasp(left=1, right=1), values, None) is None
    said = GRASP.apply(sim, grasp(left=1, right=1), values)
    assert said == 'left closed on 1 particles; right closed on 1 particles'
    for k in range(1, 201):                             # up 10 cm over 0.2 s, then held
        for frame, corner in zip(('left', 'right'), corners):
            FRAME_POSE.apply(sim, frame_pose(frame, corner + [0, 0, 0.1 * min(k / 100, 1)]),
                             values)
        sim.step(1)
    np.testing.assert_allclose(sim.positions()[[0, 9]], corners + [0, 0, 0.1], atol=2e-3)
    assert GRASP.apply(sim, grasp(left=0, right=0), values) == (
        'left opened: 1 particles let go; right opened: 1 particles let go')
    sim.step(300)                                       # let go: they fall back
    assert (sim.positions()[[0, 9], 2] < corners[:, 2] + 0.09).all()
    FRAME_POSE.apply(sim, frame_pose('left', corners[0] + [0, 0.5, 0]), values)
    assert 'nothing within reach of left' in GRASP.apply(sim, grasp(left=1), values)
    assert 'thumb is not a gripper' in GRASP.refusal(grasp(thumb=1), values, None)
    assert 'one position for each name' in GRASP.refusal(JointState(name=['left']), values,
                                                         None)
    assert recorded_messages(GRASP, grasp(left=1)) == [('/grasp', grasp(left=1))]


def marker(kind: int = Marker.CUBE, action: int = Marker.ADD, position=(0.0, 0.0, 0.0),
           scale=(2.0, 2.0, 0.1), ns: str = 'table', marker_id: int = 0,
           frame_id: str = 'world') -> Marker:
    m = Marker(type=kind, action=action, ns=ns, id=marker_id)
    m.header.frame_id = frame_id
    m.pose.position.x, m.pose.position.y, m.pose.position.z = (float(v) for v in position)
    m.scale.x, m.scale.y, m.scale.z = (float(v) for v in scale)
    return m                       # orientation all zero: no turn, as RViz takes it


def test_a_marker_added_is_a_collider_moved_on_its_id_and_deleted():
    """A CUBE under the sheet's bottom edge holds it up; DELETE lets it go; bad ones refused."""
    sim = build_simulation(variant('sheet_10x10', anchor_motion=[]),
                           SimulationConfig(method='full'))
    sim.step(1000)
    bottom = float(sim.positions()[:10, 2].min())
    table = marker(position=(0.45, 0.0, bottom - 0.05))    # its top at the bottom edge
    assert COLLIDER_MARKER.refusal(table, VALUES, None) is None
    assert COLLIDER_MARKER.apply(sim, table, VALUES) == 'collider table/0 placed (1 added)'
    for k in range(1, 101):                                  # the same shape: moved 5 cm up
        moving = marker(position=(0.45, 0.0, bottom - 0.05 + 0.0005 * k))
        COLLIDER_MARKER.apply(sim, moving, VALUES)
        sim.step(1)
    sim.step(500)
    assert sim.positions()[:10, 2].min() > bottom + 0.04          # the edge rests on it
    assert COLLIDER_MARKER.apply(sim, marker(action=Marker.DELETE), VALUES) == (
        'collider table/0 removed: 0 added left')
    sim.step(2000)
    assert sim.positions()[:10, 2].min() < bottom + 0.01          # fell back
    for bad, why in ((marker(kind=Marker.ARROW), 'a collider is a SPHERE, CUBE or CYLINDER'),
                     (marker(scale=(1.0, 0.0, 1.0)), 'scale must be positive'),
                     (marker(position=(math.inf, 0, 0)), 'non-finite'),
                     (marker(action=1), 'action 1')):
        assert why in COLLIDER_MARKER.refusal(bad, VALUES, None)
    assert recorded_messages(COLLIDER_MARKER, table) == [('/collider_marker', table)]

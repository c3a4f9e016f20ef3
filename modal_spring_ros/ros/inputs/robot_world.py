"""
The robot's world as inputs: where frames are, grippers closing, colliders drawn as markers.

What :mod:`~modal_spring_ros.ros.inputs.input_kinds` declares for ``frame_pose``
(``geometry_msgs/TransformStamped``), ``grasp`` (``sensor_msgs/JointState``) and
``collider_marker`` (``visualization_msgs/Marker``) does here: each input's checks, its effect
on the run (:meth:`~modal_spring_ros.core.loads.holder.LoadHolder.move_frame`,
``close_gripper``, ``add_collider``) and its carrying into the node's frame through TF.
"""
from __future__ import annotations

import copy
import math
from typing import Any

from geometry_msgs.msg import Point, Pose, PoseStamped, Quaternion, TransformStamped
from modal_spring_ros.core.loads.grasp import GraspError
from modal_spring_ros.core.loads.wrench import default_radius
from modal_spring_ros.core.model.colliders import (Box, Collider, Cylinder, Pose as ColliderPose,
                                                   Sphere)
from modal_spring_ros.core.motion.clamp_follower import QUATERNION_TOLERANCE
from modal_spring_ros.core.simulations import Simulation
from modal_spring_ros.ros.frames.frame_tree import Transform
from modal_spring_ros.ros.frames.tf import transform_message
import numpy as np
from sensor_msgs.msg import JointState
from std_msgs.msg import Header
from visualization_msgs.msg import Marker

#: the marker types a collider can be made from
MARKER_SHAPES = (Marker.SPHERE, Marker.CUBE, Marker.CYLINDER)
#: the largest marker taken as a collider, m
MAX_MARKER_SIZE = 1000.0


def pose_message(transform: Transform, header: Header) -> PoseStamped:
    """Return the pose of a frame whose transform into ``header.frame_id`` is ``transform``."""
    (x, y, z), (qx, qy, qz, qw) = transform.translation.tolist(), transform.rotation.tolist()
    return PoseStamped(header=header, pose=Pose(position=Point(x=x, y=y, z=z),
                                                orientation=Quaternion(x=qx, y=qy, z=qz, w=qw)))


def interaction_radius(sim: Simulation, values: dict[str, Any]) -> float:
    """Return ``interaction.radius``, or the scene's default for 0."""
    return values['interaction.radius'] or default_radius(sim.model)


def transform_arrays(message: TransformStamped) -> tuple[np.ndarray, np.ndarray]:
    """Return a transform's translation and quaternion (x, y, z, w)."""
    t, q = message.transform.translation, message.transform.rotation
    return np.array([t.x, t.y, t.z]), np.array([q.x, q.y, q.z, q.w])


def frame_refusal(message: TransformStamped, values: dict[str, Any], clamp) -> str | None:
    position, quaternion = transform_arrays(message)
    if not (np.isfinite(position).all() and np.isfinite(quaternion).all()):
        return 'non-finite values'
    norm = float(np.linalg.norm(quaternion))
    if abs(norm - 1.0) > QUATERNION_TOLERANCE:
        return f'the rotation is not a unit quaternion (norm {norm:.4g})'
    if not message.child_frame_id.strip('/'):
        return 'no child_frame_id (the frame the colliders are attached to)'
    return None


def apply_frame(sim: Simulation, message: TransformStamped, values: dict[str, Any]) -> str:
    position, quaternion = transform_arrays(message)
    frame = message.child_frame_id.lstrip('/')
    moved = sim.move_frame(frame, ColliderPose.of(position, quaternion))
    return (f'{frame} moved: {moved} collider{"s" * (moved != 1)} or gripper on it' if moved
            else f'{frame} moved: no collider or closed gripper is on it')


def gripper_frames(values: dict[str, Any]) -> tuple[str, ...]:
    """Return the gripper frames ``grasp.frames`` names (spaces or commas between)."""
    return tuple(f.lstrip('/') for f in values.get('grasp.frames', '').replace(',', ' ').split())


def grasp_refusal(message: JointState, values: dict[str, Any], clamp) -> str | None:
    grippers = gripper_frames(values)
    if not message.name or len(message.position) != len(message.name):
        return 'one position for each name is needed (1 closes a gripper, 0 opens it)'
    if not all(math.isfinite(p) for p in message.position):
        return 'non-finite position'
    unknown = [n for n in message.name if n.lstrip('/') not in grippers]
    if unknown:
        return f"{unknown[0]} is not a gripper (grasp.frames: {', '.join(grippers)})"
    return None


def apply_grasp(sim: Simulation, message: JointState, values: dict[str, Any]) -> str:
    """Close each named gripper whose position is above one half, open the others."""
    reach = values['grasp.reach'] or interaction_radius(sim, values)
    said = []
    for name, position in zip(message.name, message.position):
        frame = name.lstrip('/')
        if position <= 0.5:
            said.append(f'{frame} opened: {sim.open_gripper(frame)} particles let go')
            continue
        try:
            said.append(f'{frame} closed on {sim.close_gripper(frame, reach)} particles')
        except GraspError as exc:
            said.append(f'{frame} cannot close: {exc}')
    return '; '.join(said)


def transform_to_frame(message: TransformStamped, transform: Transform, frame: str
                       ) -> TransformStamped:
    position, quaternion = transform_arrays(message)
    if not (np.isfinite(position).all() and np.isfinite(quaternion).all()):
        return message          # refused as it is, with its reason
    moved = transform.then(Transform(position, quaternion))
    return transform_message(frame, message.child_frame_id, moved, message.header.stamp)


def marker_pose(marker: Marker) -> tuple[np.ndarray, np.ndarray]:
    """Return a marker's position and quaternion (an all-zero one is no turn, as RViz takes it)."""
    p, q = marker.pose.position, marker.pose.orientation
    quaternion = np.array([q.x, q.y, q.z, q.w])
    return np.array([p.x, p.y, p.z]), (quaternion if quaternion.any() else np.array(
        [0.0, 0.0, 0.0, 1.0]))


def marker_collider(marker: Marker) -> Collider:
    """Return the collider a SPHERE, CUBE or CYLINDER marker draws, at its own origin."""
    s = np.array([marker.scale.x, marker.scale.y, marker.scale.z])
    if marker.type == Marker.SPHERE:
        return Sphere(np.zeros(3), 0.5 * float(s.max()))     # no smaller than it is drawn
    if marker.type == Marker.CUBE:
        return Box(np.zeros(3), 0.5 * s)
    return Cylinder(np.zeros(3), np.array([0.0, 0.0, 1.0]), 0.5 * float(s[:2].max()),
                    0.5 * float(s[2]))


def marker_key(marker: Marker) -> str:
    return f'{marker.ns}/{marker.id}'


def marker_refusal(marker: Marker, values: dict[str, Any], clamp) -> str | None:
    if marker.action == Marker.DELETE or marker.action == Marker.DELETEALL:
        return None
    if marker.action != Marker.ADD:
        return f'action {marker.action} (ADD, DELETE or DELETEALL)'
    if marker.type not in MARKER_SHAPES:
        return (f'type {marker.type}: a collider is a SPHERE, CUBE or CYLINDER marker')
    position, quaternion = marker_pose(marker)
    scale = np.array([marker.scale.x, marker.scale.y, marker.scale.z])
    if not (np.isfinite(position).all() and np.isfinite(quaternion).all()
            and np.isfinite(scale).all()):
        return 'non-finite values'
    if not (scale > 0.0).all() or scale.max() > MAX_MARKER_SIZE:
        return f'scale must be positive and at most {MAX_MARKER_SIZE:g} m'
    norm = float(np.linalg.norm(quaternion))
    if abs(norm - 1.0) > QUATERNION_TOLERANCE:
        return f'the orientation is not a unit quaternion (norm {norm:.4g})'
    return None


def apply_marker(sim: Simulation, marker: Marker, values: dict[str, Any]) -> str:
    key = marker_key(marker)
    if marker.action == Marker.DELETEALL:
        sim.remove_collider(None)
        return 'every added collider removed'
    if marker.action == Marker.DELETE:
        return f'collider {key} removed: {sim.remove_collider(key)} added left'
    position, quaternion = marker_pose(marker)
    count = sim.add_collider(key, marker_collider(marker), ColliderPose.of(position, quaternion))
    return f'collider {key} placed ({count} added)'


def marker_to_frame(marker: Marker, transform: Transform, frame: str) -> Marker:
    position, quaternion = marker_pose(marker)
    if not (np.isfinite(position).all() and np.isfinite(quaternion).all()):
        return marker           # refused as it is, with its reason
    moved = transform.then(Transform(position, quaternion))
    carried = copy.copy(marker)
    carried.header = Header(stamp=marker.header.stamp, frame_id=frame)
    carried.pose = pose_message(moved, carried.header).pose
    return carried

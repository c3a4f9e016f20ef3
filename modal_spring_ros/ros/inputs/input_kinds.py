"""
Every ROS input the node takes, declared once.

The node, the simulation thread, the capture and re-simulation all read this table. An
:class:`InputKind` says where an input comes from (topic, message type, when the node subscribes),
when a message is refused, what an accepted one does to the running simulation (given the parameter
values it arrived with), and where a capture keeps it. The node subscribes to each kind it wants
(:mod:`~modal_spring_ros.ros.inputs.subscriptions`), an accepted message reaches the simulation
thread as one :class:`~modal_spring_ros.ros.changes.requests.TakeInput`, the thread applies it and
hands it to the capture under ``recorded_topic``, and :mod:`~modal_spring_ros.ros.tools.resimulate`
applies each recorded message with the same ``apply`` at the simulation time it took effect. A new
input is one entry of :data:`INPUTS`.

- ``anchor_pose`` (``geometry_msgs/PoseStamped``, with ``anchor.source`` topic; with tf, the
  pose of ``anchor.frame`` from TF, :mod:`~modal_spring_ros.ros.inputs.subscriptions`): the clamp
  follows each accepted pose through its filter
  (:class:`~modal_spring_ros.core.motion.clamp_follower.ClampFollower`), which also judges it
  (non-finite values, a quaternion that is not a unit one, a first pose beyond the clamp's reach,
  a jump past ``anchor.max_jump_m`` or a turn past ``anchor.max_turn_deg`` from the last pose
  accepted).
- ``/clicked_point`` (``geometry_msgs/PointStamped``, what RViz's "Publish Point" tool sends):
  the particle nearest to the point is pulled toward it
  (:mod:`~modal_spring_ros.core.loads.pull`).
- ``wrench`` (``geometry_msgs/WrenchStamped``): a force and a torque at the origin of its frame,
  spread over the free particles within ``interaction.radius`` of it for
  ``interaction.hold_s`` or until a zero wrench (:mod:`~modal_spring_ros.core.loads.wrench`).
  Carried into the node's frame it becomes a :class:`WrenchAt` (the wrench on the node's axes
  and the point it acts at), which a capture keeps as two messages: the point on
  ``/wrench_point``, then the wrench on ``/wrench`` (``recorded_point_topic``).
- ``frame_pose`` (``geometry_msgs/TransformStamped``, as TF carries a frame; also looked up
  from TF for every frame a scene's collider is attached to and every gripper of
  ``grasp.frames``, whenever TF changes it): the run is told where ``child_frame_id`` is, and
  the colliders and the closed gripper on it go there
  (:meth:`~modal_spring_ros.core.loads.holder.LoadHolder.move_frame`).
- ``grasp`` (``sensor_msgs/JointState``, as a gripper's joint is reported): each named gripper
  (a frame of ``grasp.frames``) closes with a position above one half, holding the free
  particles within ``grasp.reach`` of it (:mod:`~modal_spring_ros.core.loads.grasp`), and opens
  with one at or below it.
- ``collider_marker`` (``visualization_msgs/Marker``, as RViz draws a primitive): a SPHERE, CUBE
  or CYLINDER marker added is a collider the object touches from then on, where the marker is
  (its pose, carried into the node's frame through TF); added again on its ``ns/id`` it moves
  (the same shape) or changes; DELETE removes it, DELETEALL every one
  (:mod:`~modal_spring_ros.core.loads.added_colliders`).
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any, Callable

from geometry_msgs.msg import (Point, PointStamped, PoseStamped, TransformStamped, Vector3,
                               Wrench, WrenchStamped)
from modal_spring_ros.core.loads.pull import make_pull, nearest_free_particle
from modal_spring_ros.core.loads.wrench import make_wrench
from modal_spring_ros.core.simulations import Simulation
from modal_spring_ros.ros.frames.frame_tree import Transform
from modal_spring_ros.ros.inputs.robot_world import (apply_frame, apply_grasp, apply_marker,
                                                     frame_refusal, grasp_refusal,
                                                     gripper_frames, interaction_radius,
                                                     marker_key, marker_refusal,
                                                     marker_to_frame, pose_message,
                                                     transform_to_frame)
import numpy as np
from sensor_msgs.msg import JointState
from std_msgs.msg import Header
from visualization_msgs.msg import Marker


@dataclasses.dataclass(frozen=True)
class InputKind:
    """One input: its topic and type, its checks, its effect and its place in a capture."""

    name: str
    topic: str                  # as subscribed: relative names follow the node's namespace
    message_type: type
    recorded_topic: str         # where a capture keeps it
    #: whether the node subscribes, given its parameter values
    wanted: Callable[[dict[str, Any]], bool]
    #: why a message is refused (its frame is checked before), or None; given the message, the
    #: parameter values and the scene's clamp (its follower with ``anchor.source`` topic)
    refusal: Callable[[Any, dict[str, Any], Any], str | None]
    #: what an accepted message does, from the simulation's time on; returns what happened
    apply: Callable[[Simulation, Any, dict[str, Any]], str]
    #: the message carried into another frame (given the transform from its frame, and that
    #: frame's name): an input stamped in a robot's frame, through TF; None: taken in the
    #: node's frame only
    to_frame: Callable[[Any, Transform, str], Any] | None = None
    #: where a capture keeps the point an input acts at, just before the input (a wrench
    #: carried through TF acts at its frame's origin, which the node's frame does not name)
    recorded_point_topic: str | None = None
    #: whether a message is in a frame (its header's ``frame_id`` checked, carried through TF);
    #: a command (a gripper closing, a marker deleted) is not
    in_frame: Callable[[Any], bool] = lambda message: True
    #: what a message is about: a newer one of the same key replaces it before it is taken
    #: (the last pose of a frame wins; another frame's pose does not replace it)
    key: Callable[[Any], Any] = lambda message: None
    #: messages kept waiting on its topic (1: the newest; more where messages are about
    #: different things: several frames' poses, several grippers)
    depth: int = 1


@dataclasses.dataclass(frozen=True)
class WrenchAt:
    """A wrench on the node's axes (``message``) and the point it acts at (``point``)."""

    message: WrenchStamped
    point: PointStamped

    @property
    def header(self) -> Header:
        return self.message.header

    @classmethod
    def of(cls, message: 'WrenchStamped | WrenchAt') -> 'WrenchAt':
        """Return ``message`` as a wrench at a point (a WrenchStamped acts at its origin)."""
        if isinstance(message, WrenchAt):
            return message
        return cls(message, PointStamped(header=message.header))

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return the point, the force and the torque, (3,) each."""
        p, w = self.point.point, self.message.wrench
        return (np.array([p.x, p.y, p.z]), _vector(w.force), _vector(w.torque))

    def recorded(self) -> list[tuple[str, Any]]:
        """Return what a capture keeps: the point, then the wrench (topics as recorded)."""
        return [(WRENCH.recorded_point_topic, self.point), (WRENCH.recorded_topic, self.message)]


def pose_arrays(message: PoseStamped) -> tuple[np.ndarray, np.ndarray]:
    p, q = message.pose.position, message.pose.orientation
    return np.array([p.x, p.y, p.z]), np.array([q.x, q.y, q.z, q.w])


def _pose_to_frame(message: PoseStamped, transform: Transform, frame: str) -> PoseStamped:
    position, quaternion = pose_arrays(message)
    if not (np.isfinite(position).all() and np.isfinite(quaternion).all()):
        return message          # refused as it is, with its reason
    moved = transform.then(Transform(position, quaternion))
    return pose_message(moved, Header(stamp=message.header.stamp, frame_id=frame))


def _point_to_frame(message: PointStamped, transform: Transform, frame: str) -> PointStamped:
    p = message.point
    x, y, z = transform.apply(np.array([p.x, p.y, p.z])).tolist()
    return PointStamped(header=Header(stamp=message.header.stamp, frame_id=frame),
                        point=Point(x=x, y=y, z=z))


def _pose_refusal(message: PoseStamped, values: dict[str, Any], clamp) -> str | None:
    position, quaternion = pose_arrays(message)
    return clamp.check(position, quaternion, values['anchor.max_jump_m'],
                       math.radians(values['anchor.max_turn_deg']))


def _apply_pose(sim: Simulation, message: PoseStamped, values: dict[str, Any]) -> str:
    position, quaternion = pose_arrays(message)
    sim.model.motion.follow(sim.time, position, quaternion)
    return 'following the pose'


def _click_refusal(message: PointStamped, values: dict[str, Any], clamp) -> str | None:
    p = message.point
    return None if all(math.isfinite(v) for v in (p.x, p.y, p.z)) else 'non-finite point'


def _apply_click(sim: Simulation, message: PointStamped, values: dict[str, Any]) -> str:
    """
    Pick and place: a click on the object grabs, the next click takes what it grabbed there.

    A click within ``interaction.radius`` of a free particle is on the object: with nothing
    held (or on the held particle itself) it grabs the nearest particle where it is (pulled
    toward its own position); while a particle is held, any other click pulls that particle
    toward the point. A click off the object with nothing held pulls the nearest particle.
    """
    point = np.array([message.point.x, message.point.y, message.point.z])
    positions = sim.positions()
    particle = nearest_free_particle(sim.model, positions, point)
    reach = interaction_radius(sim, values)
    on_object = float(np.linalg.norm(positions[particle] - point)) <= reach
    held = sim.pull.particle if sim.pull is not None and sim.time <= sim.pull.until else None
    if held is not None and held != particle:
        particle, what = held, f'taking particle {held} to the point'
    elif on_object:
        point, what = positions[particle], f'grabbed particle {particle}: click where to take it'
    else:
        what = f'pulling particle {particle}'
    sim.start_pull(make_pull(sim.model, particle, point, values['interaction.stiffness'],
                             values['interaction.max_force_n'], sim.time,
                             values['interaction.hold_s']))
    return what


def _vector(v: Vector3) -> np.ndarray:
    return np.array([v.x, v.y, v.z])


def _vector3(v: np.ndarray) -> Vector3:
    x, y, z = (float(c) for c in v)
    return Vector3(x=x, y=y, z=z)


def _wrench_to_frame(message: WrenchStamped, transform: Transform, frame: str) -> WrenchAt:
    header = Header(stamp=message.header.stamp, frame_id=frame)
    w = message.wrench
    wrench = Wrench(force=_vector3(transform.rotate(_vector(w.force))),
                    torque=_vector3(transform.rotate(_vector(w.torque))))
    x, y, z = transform.translation.tolist()
    return WrenchAt(WrenchStamped(header=header, wrench=wrench),
                    PointStamped(header=header, point=Point(x=x, y=y, z=z)))


def _wrench_refusal(message, values: dict[str, Any], clamp) -> str | None:
    arrays = WrenchAt.of(message).arrays()
    return None if all(np.isfinite(a).all() for a in arrays) else 'non-finite values'


def _apply_wrench(sim: Simulation, message, values: dict[str, Any]) -> str:
    point, force, torque = WrenchAt.of(message).arrays()
    if not (force.any() or torque.any()):
        sim.start_wrench(None)
        return 'wrench ended (a zero wrench)'
    wrench = make_wrench(sim.model, sim.positions(), point, force, torque,
                         interaction_radius(sim, values),
                         values['interaction.max_force_n'], sim.time, values['interaction.hold_s'])
    sim.start_wrench(wrench)
    capped = ' (capped)' if wrench.capped else ''
    return (f'pushing {wrench.particles.size} particles with {np.linalg.norm(wrench.force):.3g} N'
            f' and {np.linalg.norm(wrench.torque):.3g} N m{capped}')


def recorded_messages(kind: InputKind, received) -> list[tuple[str, Any]]:
    """Return the (topic, message) pairs a capture keeps for an input ``kind`` applied."""
    if isinstance(received, WrenchAt):
        return received.recorded()
    return [(kind.recorded_topic, received)]


ANCHOR_POSE = InputKind('anchor_pose', 'anchor_pose', PoseStamped, '/anchor_pose',
                        wanted=lambda values: values['anchor.source'] == 'topic',
                        refusal=_pose_refusal, apply=_apply_pose, to_frame=_pose_to_frame)
CLICKED_POINT = InputKind('clicked_point', '/clicked_point', PointStamped, '/clicked_point',
                          wanted=lambda values: True, refusal=_click_refusal, apply=_apply_click,
                          to_frame=_point_to_frame)
WRENCH = InputKind('wrench', 'wrench', WrenchStamped, '/wrench', wanted=lambda values: True,
                   refusal=_wrench_refusal, apply=_apply_wrench, to_frame=_wrench_to_frame,
                   recorded_point_topic='/wrench_point')
FRAME_POSE = InputKind('frame_pose', 'frame_pose', TransformStamped, '/frame_pose',
                       wanted=lambda values: True, refusal=frame_refusal, apply=apply_frame,
                       to_frame=transform_to_frame,
                       key=lambda message: message.child_frame_id.lstrip('/'), depth=16)
GRASP = InputKind('grasp', 'grasp', JointState, '/grasp',
                  wanted=lambda values: bool(gripper_frames(values)), refusal=grasp_refusal,
                  apply=apply_grasp, in_frame=lambda message: False,
                  key=lambda message: tuple(n.lstrip('/') for n in message.name), depth=16)
COLLIDER_MARKER = InputKind('collider_marker', 'collider_marker', Marker, '/collider_marker',
                            wanted=lambda values: True, refusal=marker_refusal,
                            apply=apply_marker, to_frame=marker_to_frame,
                            in_frame=lambda marker: marker.action == Marker.ADD,
                            key=lambda marker: (marker.action == Marker.DELETEALL
                                                or marker_key(marker)), depth=16)
#: the node's inputs
INPUTS: tuple[InputKind, ...] = (ANCHOR_POSE, CLICKED_POINT, WRENCH, FRAME_POSE, GRASP,
                                 COLLIDER_MARKER)

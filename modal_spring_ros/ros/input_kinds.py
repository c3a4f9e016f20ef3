"""
Every ROS input the node takes, declared once.

The node, the simulation thread, the capture and re-simulation all read this table. An
:class:`InputKind` says where an input comes from (topic, message type, when the node
subscribes), when a message is refused, what an accepted one does to the running simulation
(given the parameter values it arrived with), and where a capture keeps it. The node subscribes
to each kind it wants (:mod:`~modal_spring_ros.ros.inputs`), an accepted message reaches the
simulation thread as one :class:`~modal_spring_ros.ros.requests.TakeInput`, the thread applies it
and hands it to the capture under ``recorded_topic``, and
:mod:`~modal_spring_ros.ros.resimulate` applies each recorded message with the same ``apply``
at the simulation time it took effect. A new input is one entry of :data:`INPUTS`.

- ``anchor_pose`` (``geometry_msgs/PoseStamped``, with ``anchor.source`` topic): the clamp
  follows each accepted pose through its filter
  (:class:`~modal_spring_ros.core.motion.clamp_follower.ClampFollower`), which also judges it
  (non-finite values, a quaternion that is not a unit one, a first pose beyond the clamp's reach,
  a jump past ``anchor.max_jump_m`` or a turn past ``anchor.max_turn_deg`` from the last pose
  accepted).
- ``/clicked_point`` (``geometry_msgs/PointStamped``, what RViz's "Publish Point" tool sends):
  the particle nearest to the point is pulled toward it
  (:mod:`~modal_spring_ros.core.motion.pull`).
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any, Callable

from geometry_msgs.msg import PointStamped, PoseStamped
from modal_spring_ros.core.motion.pull import make_pull, nearest_free_particle
from modal_spring_ros.core.simulations import Simulation
import numpy as np


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


def pose_arrays(message: PoseStamped) -> tuple[np.ndarray, np.ndarray]:
    p, q = message.pose.position, message.pose.orientation
    return np.array([p.x, p.y, p.z]), np.array([q.x, q.y, q.z, q.w])


def _pose_refusal(message: PoseStamped, values: dict[str, Any], clamp) -> str | None:
    position, quaternion = pose_arrays(message)
    return clamp.check(position, quaternion, values['anchor.max_jump_m'],
                       math.radians(values['anchor.max_turn_deg']))


def _apply_pose(sim: Simulation, message: PoseStamped, values: dict[str, Any]) -> str:
    position, quaternion = pose_arrays(message)
    sim.model.scene.anchor_motion.follow(sim.time, position, quaternion)
    return 'following the pose'


def _click_refusal(message: PointStamped, values: dict[str, Any], clamp) -> str | None:
    p = message.point
    return None if all(math.isfinite(v) for v in (p.x, p.y, p.z)) else 'non-finite point'


def _apply_click(sim: Simulation, message: PointStamped, values: dict[str, Any]) -> str:
    point = np.array([message.point.x, message.point.y, message.point.z])
    particle = nearest_free_particle(sim.model, sim.positions(), point)
    sim.start_pull(make_pull(sim.model, particle, point, values['interaction.stiffness'],
                             values['interaction.max_force_n'], sim.time,
                             values['interaction.hold_s']))
    return f'pulling particle {particle}'


ANCHOR_POSE = InputKind('anchor_pose', 'anchor_pose', PoseStamped, '/anchor_pose',
                        wanted=lambda values: values['anchor.source'] == 'topic',
                        refusal=_pose_refusal, apply=_apply_pose)
CLICKED_POINT = InputKind('clicked_point', '/clicked_point', PointStamped, '/clicked_point',
                          wanted=lambda values: True, refusal=_click_refusal, apply=_apply_click)
#: the node's inputs
INPUTS: tuple[InputKind, ...] = (ANCHOR_POSE, CLICKED_POINT)

"""
What the node takes in besides parameters: the clamp's pose and a person's clicks.

``anchor_pose`` (``geometry_msgs/PoseStamped``, with ``anchor.source`` topic): the clamp
follows each accepted pose through its filter
(:class:`~modal_spring_ros.core.motion.clamp_follower.ClampFollower`). ``/clicked_point``
(``geometry_msgs/PointStamped``, what RViz's "Publish Point" tool sends): the particle nearest
to the point is pulled toward it (:mod:`~modal_spring_ros.core.motion.pull`). A message in another
frame than the node's ``frame_id``, with non-finite values, a quaternion that is not a unit
one, a first pose beyond the clamp's reach, or a pose that jumps further than
``anchor.max_jump_m`` or turns more than ``anchor.max_turn_deg`` from the last pose accepted
is refused with a throttled warning and changes nothing. Header stamps are not used for
timing: a pose or a click takes effect when it arrives (any stamp, 0 included, is accepted).
Accepted inputs reach the simulation thread as requests, applied between two steps at the
simulation time they are recorded with (``record.bag``), so a re-simulation applies them at
the same step.
"""
from __future__ import annotations

import math
import threading
import time
from typing import Any, Callable

from geometry_msgs.msg import PointStamped, PoseStamped
from modal_spring_ros.core.motion.pull import make_pull, nearest_free_particle
from modal_spring_ros.core.simulations import Simulation
from modal_spring_ros.ros.requests import FollowPose, PullPoint, Request
import numpy as np

ANCHOR_TOPIC = 'anchor_pose'
CLICK_TOPIC = '/clicked_point'
#: no pose for this long: the clamp holds the last one, and /diagnostics says so, s
POSE_TIMEOUT_S = 0.5
#: refusals are logged at most this often, s
WARN_PERIOD_S = 2.0
QUEUE_DEPTH = 10


def pose_arrays(message: PoseStamped) -> tuple[np.ndarray, np.ndarray]:
    p, q = message.pose.position, message.pose.orientation
    return np.array([p.x, p.y, p.z]), np.array([q.x, q.y, q.z, q.w])


def apply_pose(sim: Simulation, message: PoseStamped) -> str:
    """Make the running clamp follow ``message`` from the simulation's time on."""
    position, quaternion = pose_arrays(message)
    sim.model.scene.anchor_motion.follow(sim.time, position, quaternion)
    return 'following the pose'


def apply_click(sim: Simulation, message: PointStamped, stiffness: float, max_force: float,
                hold_s: float) -> str:
    """Pull the particle nearest to the clicked point toward it, from the simulation's time."""
    point = np.array([message.point.x, message.point.y, message.point.z])
    particle = nearest_free_particle(sim.model, sim.positions(), point)
    sim.start_pull(make_pull(sim.model, particle, point, stiffness, max_force, sim.time,
                             hold_s))
    return f'pulling particle {particle}'


class NodeInputs:
    """The node's subscriptions; accepted messages go to ``submit`` as requests."""

    def __init__(self, node, follower, values: Callable[[], dict[str, Any]],
                 submit: Callable[[Request], Request], callback_group=None):
        """``follower``: the clamp's follower when ``anchor.source`` is topic, else None."""
        self._node = node
        self._follower = follower
        self._values = values
        self._submit = submit
        self._lock = threading.Lock()
        self._last_pose = 0.0        # monotonic time of the last accepted pose
        self._last_warning = -math.inf
        self.refused = 0
        if follower is not None:
            node.create_subscription(PoseStamped, ANCHOR_TOPIC, self._on_pose, QUEUE_DEPTH,
                                     callback_group=callback_group)
        node.create_subscription(PointStamped, CLICK_TOPIC, self._on_click, QUEUE_DEPTH,
                                 callback_group=callback_group)

    def anchor_status(self) -> tuple[str, bool]:
        """Return what the clamp follows, and whether that is stale (no pose for a while)."""
        if self._follower is None:
            return '', False
        if not self._last_pose:
            return f'waiting for the first pose on {ANCHOR_TOPIC}', False
        age = time.monotonic() - self._last_pose
        refused = f'; {self.refused} refused' if self.refused else ''
        if age > POSE_TIMEOUT_S:
            return f'no pose for {age:.1f} s: holding the last{refused}', True
        return f'following {ANCHOR_TOPIC} (last pose {age:.2f} s ago){refused}', False

    def _refuse(self, what: str, why: str) -> None:
        # throttled here, not by the logger: rclpy's throttle looks up its caller's source line
        # on every call (0.5 ms), which a flood of bad messages would spend on nothing
        now = time.monotonic()
        with self._lock:
            self.refused += 1
            if now - self._last_warning < WARN_PERIOD_S:
                return
            self._last_warning = now
        self._node.get_logger().warning(f'{what} refused: {why}')

    def _frame_problem(self, frame_id: str) -> str | None:
        expected = self._values()['frame_id']
        if frame_id != expected:
            return f"frame_id '{frame_id}' is not the node's frame_id '{expected}'"
        return None

    def _on_pose(self, message: PoseStamped) -> None:
        problem = self._frame_problem(message.header.frame_id)
        if problem is None:
            position, quaternion = pose_arrays(message)
            values = self._values()
            problem = self._follower.check(position, quaternion, values['anchor.max_jump_m'],
                                           math.radians(values['anchor.max_turn_deg']))
        if problem is not None:
            self._refuse(ANCHOR_TOPIC, problem)
            return
        self._last_pose = time.monotonic()
        self._submit(FollowPose(received=message))

    def _on_click(self, message: PointStamped) -> None:
        problem = self._frame_problem(message.header.frame_id)
        p = message.point
        if problem is None and not all(math.isfinite(v) for v in (p.x, p.y, p.z)):
            problem = 'non-finite point'
        if problem is not None:
            self._refuse(CLICK_TOPIC, problem)
            return
        v = self._values()
        self._submit(PullPoint(received=message, stiffness=v['interaction.stiffness'],
                               max_force=v['interaction.max_force_n'],
                               hold_s=v['interaction.hold_s']))

"""
The node's subscriptions: one for each input of the table (``ros/inputs/input_kinds.py``).

A message stamped in another frame than the node's ``frame_id`` is carried into it through TF
(:mod:`~modal_spring_ros.ros.frames.tf`: the latest transforms heard on ``/tf`` and
``/tf_static``); one whose frame TF cannot reach, or one its kind refuses, is refused with a
throttled warning and changes nothing. With ``anchor.source`` tf the clamp follows the pose of
``anchor.frame`` in ``frame_id``, looked up whenever TF changes and taken as an ``anchor_pose``
(judged, recorded and re-simulated as one); so is each frame a scene's collider is attached to,
taken as a ``frame_pose``. Header stamps are not used for timing: an input takes
effect when it arrives (any stamp, 0 included, is accepted). Accepted inputs reach the simulation
thread as :class:`~modal_spring_ros.ros.changes.requests.TakeInput` requests, with the parameter
values they arrived with, applied between two steps at the simulation time they are recorded with
(``record.bag``), so a re-simulation applies them at the same step.
"""
from __future__ import annotations

import math
import threading
import time
from typing import Any, Callable

from builtin_interfaces.msg import Time
from modal_spring_ros.core.model.colliders import Contact
from modal_spring_ros.ros.changes.requests import Request, TakeInput
from modal_spring_ros.ros.frames.frame_tree import Transform
from modal_spring_ros.ros.frames.tf import (tf_available, TF_MISSING, TfListener,
                                            transform_message)
from modal_spring_ros.ros.inputs.input_kinds import ANCHOR_POSE, FRAME_POSE, InputKind, INPUTS
from modal_spring_ros.ros.inputs.robot_world import gripper_frames, pose_message
import numpy as np
from std_msgs.msg import Header

#: no pose for this long: the clamp holds the last one, and /diagnostics says so, s
POSE_TIMEOUT_S = 0.5
#: refusals are logged at most this often, s
WARN_PERIOD_S = 2.0


class NodeInputs:
    """The node's subscriptions; accepted messages go to ``submit`` as requests."""

    def __init__(self, node, clamp, values: Callable[[], dict[str, Any]],
                 submit: Callable[[Request], Request], kinds: tuple[InputKind, ...] = INPUTS,
                 tf_node=None, contact: Contact | None = None):
        """
        Subscribe on ``node``; TF on ``tf_node`` (a node spun on its own; None: ``node``).

        ``clamp``: the scene's clamp follower when ``anchor.source`` is topic, else None.
        ``contact``: the scene's colliders; the frames some are attached to, and the grippers'
        (``grasp.frames``), are looked up in TF whenever it changes, each taken as a
        ``frame_pose``.
        """
        self._node = node
        self._clamp = clamp
        self._values = values
        self._submit = submit
        self._lock = threading.Lock()
        self._last_taken: dict[str, float] = {}     # monotonic time of each kind's last one
        self._last_warning = -math.inf
        self.refused = 0
        wanted = values()
        self._follows_tf = wanted.get('anchor.source') == 'tf'
        self._followed: Transform | None = None     # the last pose of anchor.frame taken
        self._tf_problem = ''                       # why anchor.frame cannot be looked up
        self._tracked_frames = tuple(dict.fromkeys(
            (contact.attached if contact is not None else ()) + gripper_frames(wanted)))
        self._placed: dict[str, Transform] = {}     # each collider frame's last pose taken
        self.tf = (TfListener(tf_node or node, self._tf_changed if (
            self._follows_tf or self._tracked_frames) else None) if tf_available() else None)
        if self.tf is None:
            node.get_logger().warning(TF_MISSING)
        for kind in kinds:
            if kind.wanted(wanted):
                node.create_subscription(kind.message_type, kind.topic, self._taker(kind),
                                         kind.depth)

    def anchor_status(self) -> tuple[str, bool]:
        """Return what the clamp follows, and whether that is stale (no pose for a while)."""
        values = self._values()
        if not (ANCHOR_POSE.wanted(values) or self._follows_tf):
            return '', False
        topic = (f"TF frame '{values['anchor.frame']}'" if self._follows_tf
                 else ANCHOR_POSE.topic)
        last = self._last_taken.get(ANCHOR_POSE.name)
        if last is None:
            why = (self._tf_problem or TF_MISSING) if self._follows_tf else ''
            return f"waiting for the first pose of {topic}{': ' + why if why else ''}", False
        age = time.monotonic() - last
        refused = f'; {self.refused} refused' if self.refused else ''
        if age > POSE_TIMEOUT_S:
            return f'no pose for {age:.1f} s: holding the last{refused}', True
        return f'following {topic} (last pose {age:.2f} s ago){refused}', False

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

    def _in_frame(self, kind: InputKind, message, frame: str) -> tuple[Any, str | None]:
        """Return the message carried into ``frame`` through TF, or why it cannot be."""
        source = message.header.frame_id
        if not kind.in_frame(message) or source.lstrip('/') == frame.lstrip('/'):
            return message, None
        if self.tf is None or kind.to_frame is None:
            why = TF_MISSING if self.tf is None else 'this input is taken in it only'
            return message, f"frame_id '{source}' is not the node's frame_id '{frame}': {why}"
        transform = self.tf.lookup(frame, source)
        if isinstance(transform, str):
            return message, f"no transform from '{source}' to '{frame}': {transform}"
        return kind.to_frame(message, transform, frame), None

    def _taker(self, kind: InputKind) -> Callable[[Any], None]:
        def take(message) -> None:
            values = self._values()
            message, problem = self._in_frame(kind, message, values['frame_id'])
            if problem is None:
                problem = kind.refusal(message, values, self._clamp)
            if problem is not None:
                self._refuse(kind.topic, problem)
                return
            self._last_taken[kind.name] = time.monotonic()
            self._submit(TakeInput(kind=kind, received=message, values=dict(values)))
        return take

    def _tf_changed(self) -> None:
        if self._follows_tf:
            self._follow_tf()
        frame_id = self._values()['frame_id']
        for frame in self._tracked_frames:
            found = self.tf.lookup(frame_id, frame)
            if isinstance(found, str) or _same(found, self._placed.get(frame)):
                continue        # not known yet, or where it was
            self._placed[frame] = found
            self._taker(FRAME_POSE)(transform_message(frame_id, frame, found, Time()))

    def _follow_tf(self) -> None:
        """Take the pose of ``anchor.frame`` in ``frame_id`` when TF has changed it."""
        values = self._values()
        found = self.tf.lookup(values['frame_id'], values['anchor.frame'])
        if isinstance(found, str):
            self._tf_problem = found
            return
        self._tf_problem = ''
        if _same(found, self._followed):
            self._last_taken[ANCHOR_POSE.name] = time.monotonic()   # still there: not stale
            return
        self._followed = found
        header = Header(frame_id=values['frame_id'])
        self._taker(ANCHOR_POSE)(pose_message(found, header))


def _same(a: Transform, b: Transform | None) -> bool:
    """Tell whether two transforms are the same (None: none yet)."""
    return (b is not None and np.array_equal(a.translation, b.translation)
            and np.array_equal(a.rotation, b.rotation))

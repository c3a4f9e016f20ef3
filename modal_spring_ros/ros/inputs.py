"""
The node's subscriptions: one for each input of the table (``ros/input_kinds.py``).

A message in another frame than the node's ``frame_id``, or one its kind refuses, is refused with
a throttled warning and changes nothing. Header stamps are not used for timing: an input takes
effect when it arrives (any stamp, 0 included, is accepted). Accepted inputs reach the simulation
thread as :class:`~modal_spring_ros.ros.requests.TakeInput` requests, with the parameter values
they arrived with, applied between two steps at the simulation time they are recorded with
(``record.bag``), so a re-simulation applies them at the same step.
"""
from __future__ import annotations

import math
import threading
import time
from typing import Any, Callable

from modal_spring_ros.ros.input_kinds import ANCHOR_POSE, InputKind, INPUTS
from modal_spring_ros.ros.requests import Request, TakeInput

#: no pose for this long: the clamp holds the last one, and /diagnostics says so, s
POSE_TIMEOUT_S = 0.5
#: refusals are logged at most this often, s
WARN_PERIOD_S = 2.0
QUEUE_DEPTH = 10


class NodeInputs:
    """The node's subscriptions; accepted messages go to ``submit`` as requests."""

    def __init__(self, node, clamp, values: Callable[[], dict[str, Any]],
                 submit: Callable[[Request], Request], kinds: tuple[InputKind, ...] = INPUTS):
        """``clamp``: the scene's clamp follower when ``anchor.source`` is topic, else None."""
        self._node = node
        self._clamp = clamp
        self._values = values
        self._submit = submit
        self._lock = threading.Lock()
        self._last_taken: dict[str, float] = {}     # monotonic time of each kind's last one
        self._last_warning = -math.inf
        self.refused = 0
        wanted = values()
        for kind in kinds:
            if kind.wanted(wanted):
                node.create_subscription(kind.message_type, kind.topic, self._taker(kind),
                                         QUEUE_DEPTH)

    def anchor_status(self) -> tuple[str, bool]:
        """Return what the clamp follows, and whether that is stale (no pose for a while)."""
        if not ANCHOR_POSE.wanted(self._values()):
            return '', False
        topic = ANCHOR_POSE.topic
        last = self._last_taken.get(ANCHOR_POSE.name)
        if last is None:
            return f'waiting for the first pose on {topic}', False
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

    def _taker(self, kind: InputKind) -> Callable[[Any], None]:
        def take(message) -> None:
            values = self._values()
            frame_id = message.header.frame_id
            problem = (f"frame_id '{frame_id}' is not the node's frame_id "
                       f"'{values['frame_id']}'" if frame_id != values['frame_id']
                       else kind.refusal(message, values, self._clamp))
            if problem is not None:
                self._refuse(kind.topic, problem)
                return
            self._last_taken[kind.name] = time.monotonic()
            self._submit(TakeInput(kind=kind, received=message, values=dict(values)))
        return take

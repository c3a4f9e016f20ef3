"""
The node's progress while it prepares: logged, kept, and on ``/diagnostics`` before it streams.

A large scene takes seconds before its first frame (its modes, ``ros/start/start_up.py``), and a
monitor of ``/diagnostics`` (rqt_robot_monitor, Foxglove) would otherwise see nothing of the
node meanwhile. :class:`StartUpReport` takes the progress lines of the scene's preparation
(the basis's factor and modes, a spring sample's training): each is logged, the last is kept
(the node reports it beside the change being prepared that it came from), and from one
:data:`PERIOD_S` after the start until the run streams a thread publishes it every
:data:`PERIOD_S` as the node's status (OK, ``starting: <line>``; the executor does not spin
before the node is built); a node that starts within a period says nothing before it streams.
A stage that lasts (a large scene's modes: minutes) is logged again every :data:`LINE_PERIOD_S`
with the time it has taken, so a console that follows the log sees the node is at work.
"""
from __future__ import annotations

import contextlib
import threading
import time

from diagnostic_msgs.msg import DiagnosticArray
from modal_spring_ros.ros.stream.diagnostics import starting_array
from modal_spring_ros.ros.stream.outputs import DIAGNOSTICS_TOPIC, QUEUE_DEPTH
from rclpy.node import Node

#: how often the status is published while the node starts, s (as the running node's)
PERIOD_S = 1.0
#: how often a stage still under way is logged again, s
LINE_PERIOD_S = 5.0


class StartUpReport:
    """
    Progress lines of a node's preparation; a context in which they are on ``/diagnostics``.

    ``with report:`` publishes the last line every :data:`PERIOD_S` (from its own thread) until
    the block ends; :meth:`progress` is the callback the preparation reports through.
    """

    def __init__(self, node: Node, hardware_id: str, line_period_s: float = LINE_PERIOD_S):
        self._node = node
        self._line_period_s = line_period_s
        self._hardware_id = hardware_id
        self._lock = threading.Lock()
        self._latest = ('preparing the scene', time.monotonic())   # (line, when)
        self._started = time.monotonic()
        self._stop = threading.Event()
        self._publisher = None
        self._thread: threading.Thread | None = None

    def latest(self, since: float = 0.0) -> str:
        """Return the last progress line if it came at ``since`` (monotonic) or after, else ''."""
        with self._lock:
            line, when = self._latest
        return line if when >= since else ''

    def progress(self, line: str) -> None:
        """Log a progress line and keep it as the latest."""
        self._node.get_logger().info(line)
        with self._lock:
            self._latest = (line, time.monotonic())

    def __enter__(self) -> StartUpReport:
        self._publisher = self._node.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC,
                                                      QUEUE_DEPTH)
        self._thread = threading.Thread(target=self._publish_until_stopped, daemon=True,
                                        name='modal_spring_start_up')
        self._thread.start()
        return self

    def __exit__(self, *exc_info) -> None:
        self._stop.set()
        self._thread.join()
        self._node.destroy_publisher(self._publisher)

    def _publish_until_stopped(self) -> None:
        name = self._node.get_fully_qualified_name()
        logged = time.monotonic()
        while not self._stop.wait(PERIOD_S):    # a start within a period says nothing
            with self._lock:
                line, since = self._latest
            now = time.monotonic()
            if now - max(since, logged) >= self._line_period_s:   # a stage that lasts
                self._node.get_logger().info(f'{line} (still at it: {now - since:.0f} s)')
                logged = now
            message = starting_array(line, now - self._started, node=name,
                                     hardware_id=self._hardware_id,
                                     stamp=self._node.get_clock().now().to_msg())
            with contextlib.suppress(Exception):     # ROS shutting down (Ctrl-C while starting)
                self._publisher.publish(message)

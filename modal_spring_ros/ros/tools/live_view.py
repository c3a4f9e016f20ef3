"""
The stream in Foxglove without code: a bridge from the ROS graph to a Foxglove WebSocket server.

A small node subscribes to what ``modal_spring_node`` publishes (``points``, ``mesh`` and the
graph's ``/diagnostics``, ``/tf`` and ``/tf_static``) and hands each message on, as the
serialised bytes DDS delivered (CDR, no decoding and re-encoding), to a WebSocket server of
the Foxglove SDK (foxglove-sdk, MIT). Each channel carries its ROS type's full ``ros2msg``
definition (as rosbag2 writes it), so Foxglove decodes the messages as it decodes a ROS 2
bag. The points are handed on at most ``max_rate_hz`` a second (a 100k-particle cloud at 60 Hz
would be 100 MB/s over a WebSocket); the server drops what a slow client cannot take.

The view subscribes best effort (a slow view never holds the node back) except ``/tf_static``,
which is latched (transient local). The SDK's own log (a client's request refused, a client
gone) goes to stderr through Python's logging, a flood of one message folded
(:mod:`~modal_spring_ros.ros.process.log_limit`): a client asking for 100,000 unknown channels
costs a few lines, not 100,000.
"""
from __future__ import annotations

import dataclasses
import logging
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from modal_spring_ros.bags.messages.message_definitions import full_definition
from modal_spring_ros.ros.process.log_limit import RepeatLimit
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import PointCloud2
from visualization_msgs.msg import Marker

try:
    import foxglove
    import foxglove._foxglove_py as foxglove_native     # its log forwarding, on and off
except ImportError:     # the optional 'view' extra is not installed
    foxglove = foxglove_native = None
try:
    from tf2_msgs.msg import TFMessage
except ImportError:     # a venv without the generated tf2_msgs: no frames in the view
    TFMessage = None

#: what to do when the Foxglove SDK is missing
SDK_MISSING = ("the live view needs the Foxglove SDK: pip install '.[view]' "
               '(or pip install foxglove-sdk)')

#: the default port Foxglove's "Open connection" offers
DEFAULT_PORT = 8765
#: most clouds a second handed to the view
DEFAULT_MAX_RATE_HZ = 30.0


class ServeError(RuntimeError):
    """The server could not start on the address and port asked for."""


@dataclasses.dataclass(frozen=True)
class Forwarded:
    """One topic the view hands on: its name, type, QoS and whether it is rate-limited."""

    topic: str
    msg_type: type
    latched: bool = False
    limited: bool = False


def forwarded_topics() -> list[Forwarded]:
    """Return the topics the view hands on (TF only where its messages are installed)."""
    topics = [Forwarded('points', PointCloud2, limited=True), Forwarded('mesh', Marker),
              Forwarded('/diagnostics', DiagnosticArray)]
    if TFMessage is not None:
        topics += [Forwarded('/tf', TFMessage), Forwarded('/tf_static', TFMessage, latched=True)]
    return topics


def ros_type_name(msg_type: type) -> str:
    """Return ``pkg/msg/Type`` for a generated ROS message class."""
    package = msg_type.__module__.split('.')[0]
    return f'{package}/msg/{msg_type.__name__}'


def route_sdk_log() -> None:
    """Send the SDK's log to stderr through Python's logging, floods folded."""
    sdk = logging.getLogger('foxglove')
    if not sdk.handlers:        # not routed by a view this process ran before
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(logging.Formatter('[%(levelname)s] [%(created).9f] [%(name)s]: '
                                               '%(message)s'))
        handler.addFilter(RepeatLimit())
        sdk.addHandler(handler)
        sdk.setLevel(logging.INFO)
        sdk.propagate = False
    foxglove.set_log_level('INFO')


class LiveView:
    """
    Hands ``node``'s subscriptions on to a Foxglove WebSocket server on ``host:port``.

    Port 0 takes a free one (:attr:`port` says which). :meth:`stop` stops the server.

    :raises ServeError: the server could not start there (the port taken, an address not this
        machine's).
    """

    def __init__(self, node: Node, host: str = '127.0.0.1', port: int = DEFAULT_PORT,
                 max_rate_hz: float = DEFAULT_MAX_RATE_HZ):
        if foxglove is None:
            raise RuntimeError(SDK_MISSING)
        route_sdk_log()
        self._context = foxglove.Context()      # this view's channels, to this server only
        try:
            self._server = foxglove.start_server(name=node.get_fully_qualified_name(),
                                                 host=host, port=port, context=self._context)
        except RuntimeError as exc:     # the port is taken, the address is not this host's
            raise ServeError(str(exc)) from None
        self.port = self._server.port
        self._gap = 1.0 / float(max_rate_hz)
        self._channels = []
        try:
            for item in forwarded_topics():
                name = ros_type_name(item.msg_type)
                schema = foxglove.Schema(name=name, encoding='ros2msg',
                                         data=full_definition(name).encode())
                channel = foxglove.Channel(node.resolve_topic_name(item.topic), schema=schema,
                                           message_encoding='cdr', context=self._context)
                self._channels.append(channel)
                qos = QoSProfile(
                    depth=1 if item.latched else 5,
                    reliability=ReliabilityPolicy.RELIABLE if item.latched
                    else ReliabilityPolicy.BEST_EFFORT,
                    durability=DurabilityPolicy.TRANSIENT_LOCAL if item.latched
                    else DurabilityPolicy.VOLATILE)
                node.create_subscription(item.msg_type, item.topic,
                                         self._handler(channel, item.limited), qos, raw=True)
        except BaseException:
            self.stop()
            raise

    def _handler(self, channel, limited: bool):
        last = [-float('inf')]

        def forward(data: bytes) -> None:
            now = time.monotonic()
            if limited and now - last[0] < self._gap:
                return
            last[0] = now
            channel.log(bytes(data), log_time=time.time_ns())
        return forward

    def stop(self) -> None:
        """
        Close the channels and stop the server, the SDK's log no longer handed to Python.

        The server's threads log while it stops (a client gone, the shutdown): handed to
        Python's logging from those threads as this one stops them, that crashed the view at
        exit (a segmentation fault in the logging handler's lock, seen once in many runs).
        """
        foxglove_native.disable_logging()
        for channel in self._channels:
            channel.close()
        self._server.stop()

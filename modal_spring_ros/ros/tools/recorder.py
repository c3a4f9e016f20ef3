"""
Recording topics into a rosbag2 MCAP bag.

As ``ros2 bag record`` does (the recorder of ``modal_spring_record``).

Messages are stored exactly as they come off the wire (raw CDR from the subscription), with
the receive time as log time and the header stamp as publish time. Each topic is subscribed
once it appears, with a QoS that matches what its publishers offer (reliable and/or
transient-local only when every publisher offers it), and the offered profiles are stored.
To re-run the simulation later, the bag also keeps the simulated node's scene (its full
definition) and its parameters at the start; every later change arrives on
``/parameter_events``, and on ``applied_parameter_events`` with the simulation time it took
effect at. Stops on SIGINT/SIGTERM or after ``--duration``; the bag is then
finalised. A recorder that is killed loses at most its last chunk.
"""
from __future__ import annotations

import struct
import time
from typing import Callable

from modal_spring_ros.bags.files.applied_changes import APPLIED_TOPIC
from modal_spring_ros.bags.files.sim_time import SIM_TIME_TOPIC
from modal_spring_ros.bags.files.writer import BagWriter
from modal_spring_ros.bags.messages.message_definitions import msg_text
from modal_spring_ros.bags.messages.message_types import message_class, TypeRefused
from modal_spring_ros.bags.messages.qos import profiles_to_yaml
from modal_spring_ros.ros.stream.outputs import DIAGNOSTICS_TOPIC, MESH_TOPIC, POINTS_TOPIC
from rcl_interfaces.srv import GetParameters, ListParameters
import rclpy
from rclpy.parameter import parameter_value_to_python
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

DEFAULT_TOPICS = [POINTS_TOPIC, SIM_TIME_TOPIC, APPLIED_TOPIC, MESH_TOPIC, DIAGNOSTICS_TOPIC,
                  '/parameter_events', '/tf', '/tf_static']
#: a parameter query unanswered this long is sent again, s
ASK_AGAIN_S = 3.0
#: How often a wait for the node asks whether the recorder was told to stop, s.
STOP_CHECK_S = 0.1
#: first field types whose stamp is the message's publish time
_STAMPED_FIRST_FIELDS = ('std_msgs/Header header', 'builtin_interfaces/Time stamp')


def header_first(type_name: str) -> bool:
    """Tell whether the message starts with a Header or a Time (CDR bytes 4..12 a stamp)."""
    try:
        text = msg_text(type_name)
    except LookupError:
        return False
    for line in text.splitlines():
        line = line.split('#', 1)[0].strip()
        if line:
            return line.startswith(_STAMPED_FIRST_FIELDS)
    return False


def stamp_ns(data: bytes) -> int | None:
    """Return the leading stamp of a little-endian CDR message (after the 4-byte encapsulation)."""
    if len(data) < 12 or data[1] != 0x01:  # CDR_LE
        return None
    sec, nanosec = struct.unpack_from('<iI', data, 4)
    return sec * 1_000_000_000 + nanosec


class Recorder:

    def __init__(self, node, writer: BagWriter, topics: list[str], target: str):
        self.node = node
        self.writer = writer
        self.wanted = [node.resolve_topic_name(t) for t in topics]
        self.target = target
        self.subscribed: dict[str, object] = {}
        self.stamped: dict[str, bool] = {}
        self.node.create_timer(0.1, self.discover)
        self.discover()

    def discover(self) -> None:
        types = dict(self.node.get_topic_names_and_types())
        for topic in self.wanted:
            if topic in self.subscribed or topic not in types:
                continue
            type_name = types[topic][0]
            try:
                cls = message_class(type_name)
            except TypeRefused as exc:
                self.node.get_logger().warning(f'not recording {topic}: {exc}')
                self.subscribed[topic] = None
                continue
            offered = [info.qos_profile for info in
                       self.node.get_publishers_info_by_topic(topic)]
            self.writer.add_topic(topic, type_name, profiles_to_yaml(offered))
            self.stamped[topic] = header_first(type_name)
            self.subscribed[topic] = self.node.create_subscription(
                cls, topic, lambda data, t=topic: self.on_message(t, data),
                request_qos(offered), raw=True)
            self.node.get_logger().info(f'recording {topic} ({type_name})')

    def on_message(self, topic: str, data: bytes) -> None:
        received = time.time_ns()
        published = stamp_ns(data) if self.stamped.get(topic) else None
        self.writer.write(topic, data, received, published)


def request_qos(offered):
    """Return a subscription QoS that connects to every publisher (as rosbag2 adapts it)."""
    qos = QoSProfile(depth=100)
    if offered and all(p.reliability == ReliabilityPolicy.RELIABLE for p in offered):
        qos.reliability = ReliabilityPolicy.RELIABLE
    else:
        qos.reliability = ReliabilityPolicy.BEST_EFFORT
    if offered and all(p.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in offered):
        qos.durability = DurabilityPolicy.TRANSIENT_LOCAL
    return qos


def snapshot_parameters(node, target: str, timeout: float,
                        stopped: Callable[[], bool] = lambda: False) -> dict | None:
    """
    All parameters of node ``target`` (None when it does not answer within ``timeout``).

    ``stopped()`` true ends the wait within :data:`STOP_CHECK_S` (None: a recorder asked to
    stop).
    """
    list_client = node.create_client(ListParameters, f'{target}/list_parameters')
    get_client = node.create_client(GetParameters, f'{target}/get_parameters')
    end = time.monotonic() + timeout
    for client in (list_client, get_client):
        while not client.wait_for_service(timeout_sec=STOP_CHECK_S):
            if stopped() or time.monotonic() >= end:
                return None
    end = time.monotonic() + timeout
    listed = _ask(node, list_client, ListParameters.Request(), end, stopped)
    if listed is None:
        return None
    names = list(listed.result.names)
    values = _ask(node, get_client, GetParameters.Request(names=names), end, stopped)
    if values is None:
        return None
    return {n: parameter_value_to_python(v) for n, v in zip(names, values.values)}


def _ask(node, client, request, end: float, stopped: Callable[[], bool]):
    """
    Return ``client``'s answer to ``request`` by monotonic time ``end``, or None.

    The request is a query, so one unanswered for :data:`ASK_AGAIN_S` is sent again: a new
    client's first answer can be lost when the server has not yet matched its response reader
    (Fast DDS waits 100 ms for that, which a busy machine can exceed).
    """
    while time.monotonic() < end and not stopped():
        future = client.call_async(request)
        asked = time.monotonic()
        while (not future.done() and not stopped()
               and time.monotonic() < min(end, asked + ASK_AGAIN_S)):
            rclpy.spin_until_future_complete(node, future, timeout_sec=STOP_CHECK_S)
        if future.done():
            return future.result()
        client.remove_pending_request(future)
    return None

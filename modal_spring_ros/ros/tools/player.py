"""
Playing a bag back on its topics, as ``ros2 bag play`` does.

Raw CDR, recorded timing, recorded QoS (the player of ``modal_spring_replay``).
"""
from __future__ import annotations

import contextlib
import time

from modal_spring_ros.bags.files.reader import BagReader, POINTCLOUD2
from modal_spring_ros.bags.files.writer import BagError
from modal_spring_ros.bags.messages.message_types import message_class, TypeRefused
from modal_spring_ros.bags.messages.qos import playback_profile, profiles_from_yaml
from modal_spring_ros.ros.process.shared_memory import cloud_transport, prefer_large_shared_memory
from modal_spring_ros.ros.process.stop_signals import end_ros, init_ros, StopSignals
from modal_spring_ros.ros.stream.publication_mode import prefer_asynchronous_publication
from modal_spring_ros.scenes.resources import share_directory
import rclpy
from rclpy import get_rmw_implementation_identifier
from rclpy.executors import ExternalShutdownException


#: Longest wait for subscribers before playing anyway, s.
WAIT_S = 30.0


def play(bag: BagReader, topics: list[str] | None, rate: float = 1.0, loop: bool = False,
         wait_for_subscribers: str | None = None, ros_args: list[str] | None = None) -> int:
    """
    Publish the bag's messages (``topics``, or all) with their recorded timing and QoS.

    The timing is scaled by ``rate``, the QoS is what their publishers offered; returns how many
    were published. ``wait_for_subscribers``: hold the start until that topic (the bag's name
    for it) has a subscriber; '' for the bag's clouds (every PointCloud2 topic: what
    a viewer watches), or every topic where it has none; None: start at once. Stops at any
    moment on SIGINT or SIGTERM, the wait included.

    :raises BagError: a topic is not in the bag, or no message could be played.
    """
    topics = topics or sorted(bag.topics)
    if wait_for_subscribers and wait_for_subscribers not in topics:
        raise BagError(f'{bag.path}: --wait-for-subscribers names {wait_for_subscribers}, which '
                       f"is not played (topics: {', '.join(topics)})")
    missing = [t for t in topics if t not in bag.topics]
    if missing:
        raise BagError(f"{bag.path}: no topic {', '.join(missing)} "
                       f"(topics: {', '.join(sorted(bag.topics))})")
    installed = [t for t in topics if _installed(bag.topics[t].type_name)]
    if not installed:
        raise BagError(f'{bag.path}: no topic of an installed message type (types: '
                       f"{', '.join(sorted({bag.topics[t].type_name for t in topics}))})")
    bag.check(installed)  # every message decodes and no cloud is damaged, before playing
    # Ctrl-C and SIGTERM interrupt the one thread that plays; ROS stays up until it ends (never
    # shut down under a publisher being made: that failed with a traceback)
    stop = StopSignals().install()
    count = 0
    prefer_asynchronous_publication()  # a slow reader never holds the replay's clock
    # large clouds over Fast DDS's large shared-memory segment, as the node sends them
    largest = max((len(m.data) for m in _first_messages(bag, installed)), default=None)
    prefer_large_shared_memory(share_directory(), largest)
    init_ros(ros_args)
    try:
        node = rclpy.create_node('modal_spring_replay')
    except KeyboardInterrupt:
        end_ros()
        return count        # stopped (Ctrl-C, SIGTERM) before it began
    except BaseException:
        end_ros()
        raise
    transport = cloud_transport(largest or 0, get_rmw_implementation_identifier(),
                                share_directory())
    if transport:
        node.get_logger().info(transport)
    try:
        publishers = {}
        for t in topics:
            info = bag.topics[t]
            try:
                cls = message_class(info.type_name)
            except TypeRefused as exc:
                node.get_logger().warning(f'skipping {t}: {exc}')
                continue
            qos = playback_profile(profiles_from_yaml(info.offered_qos_profiles))
            publishers[t] = node.create_publisher(cls, t, qos)
        if wait_for_subscribers is not None:
            awaited = _awaited(bag, publishers, wait_for_subscribers)
            end = time.monotonic() + WAIT_S
            while (stop.running(node.context) and time.monotonic() < end and
                   any(p.get_subscription_count() == 0 for p in awaited)):
                time.sleep(0.05)
            time.sleep(0.5)  # the subscribers' side of discovery completes too
            if not stop.running(node.context):
                return count                        # stopped while it waited
        while True:
            start_wall = time.monotonic()
            first = None
            for m in bag.messages(list(publishers)):
                first = m.log_time_ns if first is None else first
                due = start_wall + (m.log_time_ns - first) * 1e-9 / rate
                delay = due - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
                if not stop.running(node.context):
                    return count
                publishers[m.topic].publish(m.data)
                count += 1
            if not loop:
                break
        time.sleep(0.2)  # let the last messages leave
        if count == 0:
            raise BagError(f'{bag.path}: no message could be played (no message on '
                           f"{', '.join(topics)}, or none of an installed type)")
        return count
    except (KeyboardInterrupt, ExternalShutdownException):
        return count
    finally:
        node.destroy_node()
        end_ros()


def _awaited(bag: BagReader, publishers: dict, topic: str) -> list:
    """Return the publishers whose subscribers the start waits for (see :func:`play`)."""
    if topic:
        return [publishers[topic]] if topic in publishers else []
    clouds = [p for t, p in publishers.items() if bag.topics[t].type_name == POINTCLOUD2]
    return clouds or list(publishers.values())


def _installed(type_name: str) -> bool:
    try:
        message_class(type_name)
    except TypeRefused:
        return False
    return True


def _first_messages(bag: BagReader, topics: list[str]) -> list:
    """Return the first message of each of ``topics`` that has one (their sizes)."""
    firsts = []
    for topic in topics:
        with contextlib.closing(bag.messages([topic])) as messages:
            first = next(messages, None)
        if first is not None:
            firsts.append(first)
    return firsts

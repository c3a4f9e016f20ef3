"""
The simulation time of each frame of a recording.

With every frame the node publishes a ``sensor_msgs/TimeReference`` on ``sim_time`` (beside
``points``, so a namespace or a remap of the node moves both): its header is the frame's own
(same stamp, same frame), its ``time_ref`` the simulation time the frame shows, on the stream's
clock (what ``/clock`` says with ``publish_clock``: simulation time plus ``clock.offset_s``,
never back), its ``source`` :data:`SOURCE`. Frames stamped with the node's clock (``stamp``
``auto`` without ``publish_clock``, or ``wall``) are placed in simulation time through it.
"""
from __future__ import annotations

from modal_spring_ros.bags.files.reader import BagReader
from modal_spring_ros.bags.messages.stamps import to_nanoseconds, to_seconds

#: the topic's name relative to the node (a sibling of ``points``)
SIM_TIME_TOPIC = 'sim_time'
#: ``TimeReference.source`` of the node's messages
SOURCE = 'modal_spring simulation'
#: the type a recorded ``sim_time`` topic must have
TYPE_NAME = 'sensor_msgs/msg/TimeReference'


def beside_points(points_topic: str, name: str) -> str:
    """Return the topic ``name`` beside a cloud topic (``/ns/points`` -> ``/ns/name``)."""
    return points_topic.rsplit('/', 1)[0] + '/' + name


def sim_time_topic(points_topic: str) -> str:
    """Return the ``sim_time`` topic beside a cloud topic (``/ns/points`` -> ``/ns/sim_time``)."""
    return beside_points(points_topic, SIM_TIME_TOPIC)


def simulation_times(bag: BagReader, points_topic: str) -> dict[int, float]:
    """
    Return {frame stamp, ns: simulation time on the stream's clock, s} recorded in ``bag``.

    Empty when the bag has no ``sim_time`` beside ``points_topic`` (recorded without it, or
    before the node published it). Messages of another source are ignored.

    :raises BagError: a message cannot be decoded.
    """
    topic = sim_time_topic(points_topic)
    if topic not in bag.topics or bag.topics[topic].type_name != TYPE_NAME:
        return {}
    times = {}
    for m in bag.messages([topic]):
        reference = bag.decode(m)
        if reference.source != SOURCE:
            continue
        times[to_nanoseconds(reference.header.stamp)] = to_seconds(reference.time_ref)
    return times

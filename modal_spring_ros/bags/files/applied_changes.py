"""
When each parameter change took effect, in simulation time.

The node applies a change between two steps. ``/parameter_events`` says when it was asked for
(rclpy stamps the event with the node's clock as it accepts the change), and a recording over DDS
receives that event whenever the graph delivers it: on a busy machine, frames after the frames
already stepped with the change. So with every change it applies, the node also publishes a
``rcl_interfaces/ParameterEvent`` on ``applied_parameter_events`` (beside ``points``, as
``sim_time``: a namespace or a remap of the node moves them together): its ``stamp`` the
simulation time the change took effect at, on the stream's clock (``sim_time``'s ``time_ref``:
simulation time plus ``clock.offset_s``, never back), its ``node`` the node's full name, its
``changed_parameters`` the values that reached the run (the band's and those that rebuild it).
A recording's re-simulation applies each change there, before the first frame after it. The
node's own capture writes the same event on ``/parameter_events``, stamped with simulation time.
"""
from __future__ import annotations

from typing import Any

from modal_spring_ros.bags.files.reader import BagReader
from modal_spring_ros.bags.files.sim_time import beside_points
from modal_spring_ros.bags.files.writer import BagError
from modal_spring_ros.bags.messages.stamps import to_nanoseconds, to_time_msg
from rcl_interfaces.msg import ParameterEvent
from rclpy.parameter import Parameter, parameter_value_to_python

#: the topic's name relative to the node (a sibling of ``points``)
APPLIED_TOPIC = 'applied_parameter_events'
#: the type the topic must have
TYPE_NAME = 'rcl_interfaces/msg/ParameterEvent'


def applied_topic(points_topic: str) -> str:
    """Return the applied changes' topic beside a cloud topic (``/ns/points`` -> ``/ns/...``)."""
    return beside_points(points_topic, APPLIED_TOPIC)


def parameter_event(t: float, node: str, changed: dict[str, Any]) -> ParameterEvent:
    """Return the event of ``changed`` ({name: value}) by ``node``, stamped ``t`` seconds."""
    return ParameterEvent(stamp=to_time_msg(t), node=node, changed_parameters=[
        Parameter(name, value=value).to_parameter_msg() for name, value in changed.items()])


def event_values(event) -> dict[str, Any]:
    """Return the {name: value} a ``ParameterEvent`` sets (new and changed; a decoded one too)."""
    return {p.name: parameter_value_to_python(p.value)
            for p in list(event.new_parameters) + list(event.changed_parameters)}


def applied_changes(bag: BagReader, points_topic: str,
                    node: str) -> list[tuple[int, dict[str, Any]]] | None:
    """
    Return ``node``'s changes as (published simulation time ns, {name: value}), in bag order.

    None when the bag did not record the topic beside ``points_topic`` (recorded without it, or
    before the node published it): its changes can then be placed only as ``/parameter_events``
    was received.

    :raises BagError: the topic has another type, or a message cannot be decoded.
    """
    topic = applied_topic(points_topic)
    if topic not in bag.topics:
        return None
    if bag.topics[topic].type_name != TYPE_NAME:
        raise BagError(f'{bag.path}: {topic} is {bag.topics[topic].type_name}, not {TYPE_NAME}')
    out = []
    for m in bag.messages([topic]):
        event = bag.decode(m)
        if event.node != node:
            continue
        values = event_values(event)
        if values:
            out.append((to_nanoseconds(event.stamp), values))
    return out

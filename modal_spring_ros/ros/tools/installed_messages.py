"""
A bag's messages as objects of their installed ROS classes, for what hands them on to ROS.

:meth:`~modal_spring_ros.bags.files.reader.BagReader.decode` reads any message from the bag's own
definition of its type, with no ROS at all. What passes a recorded message on to ROS code (the
re-simulation of a capture's inputs and parameter events, which the node's own input kinds and
rclpy's ``Parameter`` take) needs the installed class: the type name resolves only to an
installed interface (:mod:`~modal_spring_ros.bags.messages.message_types`), and nothing a bag says
chooses what is imported.
"""
from __future__ import annotations

from typing import Any

from modal_spring_ros.bags.files.reader import BagMessage, BagReader
from modal_spring_ros.bags.files.writer import BagError
from modal_spring_ros.bags.messages.message_types import message_class, TypeRefused
from rclpy.serialization import deserialize_message


def installed_message(bag: BagReader, message: BagMessage) -> Any:
    """
    Return ``message`` of ``bag`` as an object of its installed class (rclpy's deserializer).

    :raises BagError: its type is not installed, or its bytes are not a valid message.
    """
    try:
        cls = message_class(message.type_name)
    except TypeRefused as exc:
        raise BagError(f'{bag.path}: message on {message.topic}: {exc}') from None
    try:
        return deserialize_message(message.data, cls)
    except Exception as exc:  # rclpy raises several kinds for damaged CDR
        raise BagError(f'{bag.path}: message on {message.topic} at log time '
                       f'{message.log_time_ns} ns is damaged: cannot decode it as '
                       f'{message.type_name} ({type(exc).__name__})') from None

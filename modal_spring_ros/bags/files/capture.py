"""
Lossless capture.

A simulation run written straight to a rosbag2 MCAP bag, every frame, without going through DDS;
and the description needed to re-run it.

Frames go to ``/points`` as PointCloud2, stamped with simulation time (also the publish
time); a fixed run's log times are the wall time it was recorded at plus that stamp, so bag
tools show when it was made. A ``modal_spring_ros`` metadata record holds the scene (full
definition) and either the fixed settings (``modal_spring_sim --bag``) or the node's
parameters at the start, with every later change on ``/parameter_events`` and every input it
took (the clamp's poses on ``/anchor_pose``, clicked points on ``/clicked_point``, wrenches on
``/wrench`` with the points they acted at on ``/wrench_point``, each on the topic its caller
names) stamped with the simulation time it took effect at
(``modal_spring_node`` with ``record.bag``).
"""
from __future__ import annotations

import copy
import time

from modal_spring_ros.bags.files.applied_changes import parameter_event
from modal_spring_ros.bags.files.writer import BagWriter
from modal_spring_ros.bags.messages.pointcloud import CloudBuffer
from modal_spring_ros.bags.messages.qos import profiles_to_yaml
from modal_spring_ros.bags.messages.stamps import to_nanoseconds, to_time_msg
from modal_spring_ros.core.config import SimulationConfig
import numpy as np
from rclpy.qos import QoSPresetProfiles, QoSProfile
from std_msgs.msg import Header

POINTS_TOPIC = '/points'


def _type_name(message) -> str:
    """``package/msg/Type`` of a message instance."""
    module = type(message).__module__.split('.')[0]
    return f'{module}/msg/{type(message).__name__}'


def parameter_events_qos_yaml() -> str:
    return profiles_to_yaml([QoSPresetProfiles.PARAMETER_EVENTS.value])


def points_qos_yaml() -> str:
    """Return the QoS the node offers on ``points`` (reliable, volatile, keep last 10)."""
    return profiles_to_yaml([QoSProfile(depth=10)])


class RunBagWriter:
    """Frames of one run into a new bag; call :meth:`frame` per frame, then :meth:`close`."""

    def __init__(self, directory, scene, config: SimulationConfig | None, *, dt: float,
                 frame_every: int, duration: float, frame_id: str = 'world',
                 source: str = 'modal_spring_sim', parameters: dict | None = None,
                 node: str = ''):
        """
        ``config`` describes a run made of fixed settings.

        A node's run gives its ``parameters`` (and ``node`` name) instead, and its changes go
        through :meth:`parameter_event`, stamped with the simulation time they took effect at.
        """
        self.scene = scene
        self._cloud: CloudBuffer | None = None  # made at the first frame of positions, reused
        self.frame_id = frame_id
        self.node = node
        self.writer = BagWriter(directory, attachments=True)
        self.writer.add_topic(POINTS_TOPIC, 'sensor_msgs/msg/PointCloud2', points_qos_yaml())
        record = {'source': source, 'dt': dt,
                  'frame_every': frame_every, 'duration': duration, 'frame_id': frame_id}
        if config is not None:
            record['config'] = config.to_dict()
        #: log messages at wall time (a node's capture) rather than at their stamp
        self.wall_log_time = parameters is not None
        #: a fixed run is logged from the wall time it was recorded at (bag tools show its
        #: date, not 1970), its messages spaced as their stamps (simulation time)
        self._epoch_ns = time.time_ns()
        if parameters is not None:
            record.update(parameters=parameters, node=node, event_clock='sim')
            self.writer.add_topic('/parameter_events', 'rcl_interfaces/msg/ParameterEvent',
                                  parameter_events_qos_yaml())
        self.writer.add_run_record(record, scene)

    def parameter_event(self, t: float, changed: dict) -> None:
        """
        Record parameter changes that took effect at simulation time ``t``.

        ``t`` is the event's stamp; the event is logged at wall time, like the frames of a node's
        capture.
        """
        event = parameter_event(t, self.node, changed)
        self.writer.write_message('/parameter_events', event, self._log_time(),
                                  to_nanoseconds(event.stamp))

    def record_input(self, t: float, topic: str, message) -> None:
        """
        Record an input that took effect at simulation time ``t`` on ``topic``.

        An input is a stamped message the node took (a pose the clamp followed, a clicked point:
        :mod:`~modal_spring_ros.ros.inputs.input_kinds`), kept as received but for its header,
        stamped with ``t``.
        """
        type_name = _type_name(message)
        self.writer.add_topic(topic, type_name, points_qos_yaml())
        message = copy.deepcopy(message)
        message.header.stamp = to_time_msg(t)
        self.writer.write_message(topic, message, self._log_time(),
                                  to_nanoseconds(message.header.stamp))

    def _log_time(self) -> int | None:
        """
        Wall time for a node's capture; None for a fixed run.

        Simulation time can go back on a reset, and MCAP readers order by log time. A fixed run
        logs its start plus the stamp.
        """
        return time.time_ns() if self.wall_log_time else None

    def frame(self, t: float, positions: np.ndarray, log_time_ns: int | None = None) -> None:
        """
        Write one frame at simulation time ``t``.

        ``log_time_ns``: when re-creating a recorded frame, its original log time, so that both
        bags read in the same order.
        """
        if self._cloud is None:
            self._cloud = CloudBuffer(self.scene.rest_positions)
        self._cloud.write(positions)
        self.cloud_frame(t, self._cloud, log_time_ns)

    def cloud_frame(self, t: float, cloud: CloudBuffer, log_time_ns: int | None = None) -> None:
        """Write one frame at simulation time ``t`` from a cloud written (a node's own)."""
        stamp = to_time_msg(t)
        msg = cloud.message(Header(stamp=stamp, frame_id=self.frame_id))
        ns = to_nanoseconds(stamp)
        log = log_time_ns if log_time_ns is not None else self._log_time()
        self.writer.write_message(POINTS_TOPIC, msg, self._epoch_ns + ns if log is None else log,
                                  ns)

    def close(self) -> None:
        self.writer.close()

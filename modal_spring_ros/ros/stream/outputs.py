"""
What the node publishes: clouds, mesh markers, the clock, diagnostics, and its own capture.

:class:`NodeOutputs` is the simulation thread's
:class:`~modal_spring_ros.ros.stream.simulation_thread.Outputs` for a live node: it turns a frame
into ``sensor_msgs/PointCloud2`` (and a ``visualization_msgs/Marker`` while someone subscribes to
the mesh), writes it to the ``record.bag`` capture when there is one, and builds ``/diagnostics``
with :func:`~modal_spring_ros.ros.stream.diagnostics.diagnostic_array`.
"""
from __future__ import annotations

import contextlib
import dataclasses
from typing import Any, Callable, Protocol

from diagnostic_msgs.msg import DiagnosticArray
from modal_spring_ros.bags.files.applied_changes import APPLIED_TOPIC, parameter_event
from modal_spring_ros.bags.files.capture import RunBagWriter
from modal_spring_ros.bags.files.sim_time import SIM_TIME_TOPIC, SOURCE
from modal_spring_ros.bags.files.writer import BagError
from modal_spring_ros.bags.messages.pointcloud import CloudBuffer
from modal_spring_ros.bags.messages.stamps import to_time_msg
from modal_spring_ros.core.model.scene import Scene
from modal_spring_ros.core.simulations import Simulation, SimulationStatus
from modal_spring_ros.ros.frames.tf import FrameBroadcaster, tf_available
from modal_spring_ros.ros.markers.collider_markers import collider_markers
from modal_spring_ros.ros.markers.mesh_marker import marker_cells, mesh_marker
from modal_spring_ros.ros.parameters import broadcast_frames
from modal_spring_ros.ros.process.shared_memory import cloud_transport
from modal_spring_ros.ros.stream.diagnostics import diagnostic_array, StreamReport
from modal_spring_ros.ros.stream.stream_time import stamps_in_simulation_time, StreamTime
from modal_spring_ros.scenes.resources import share_directory
import numpy as np
from rcl_interfaces.msg import ParameterEvent
from rclpy import get_rmw_implementation_identifier
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSPolicyKind, QoSPresetProfiles, QoSProfile
from rclpy.qos_overriding_options import QoSOverridingOptions
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import PointCloud2, TimeReference
from std_msgs.msg import Header
from visualization_msgs.msg import Marker, MarkerArray

#: Topics (relative, so that namespaces and remapping apply); diagnostics and clock are global.
POINTS_TOPIC = 'points'
MESH_TOPIC = 'mesh'
COLLIDERS_TOPIC = 'colliders'
DIAGNOSTICS_TOPIC = '/diagnostics'
CLOCK_TOPIC = '/clock'
#: what a user may override in the stream's QoS at start (rclpy's default set leaves durability
#: out: a late viewer asking for transient-local frames could not have them)
OVERRIDABLE_POLICIES = (QoSPolicyKind.HISTORY, QoSPolicyKind.DEPTH, QoSPolicyKind.RELIABILITY,
                        QoSPolicyKind.DURABILITY)
#: depth of the publishers' history (keep last)
QUEUE_DEPTH = 10


class Outputs(Protocol):
    """What the thread publishes through (the node's publishers, or a test's recorder)."""

    def frame(self, sim: Simulation, cloud: CloudBuffer, mesh: bool) -> None: ...

    def diagnostics(self, status: SimulationStatus, report: StreamReport) -> None: ...

    def changed(self, sim: Simulation, changed: dict) -> None: ...

    def received(self, sim: Simulation, recorded: list[tuple[str, Any]]) -> None: ...

    def log(self, level: str, message: str) -> None: ...


class NodeOutputs:
    """The node's publishers and capture; ``values`` gives the current parameter values."""

    def __init__(self, node: Node, scene: Scene, values: Callable[[], dict[str, Any]],
                 bag: RunBagWriter | None, time: StreamTime | None = None):
        """``time`` maps simulation time to published time (default: from 0, reported nowhere)."""
        self._node = node
        self._time = time or StreamTime()
        self._scene = scene
        self._cells, self._width = marker_cells(scene)
        self._values = values
        self._bag = bag
        #: why the capture stopped ('' while it records, or when there is none)
        self.recording_stopped = ''
        # the stream's QoS can be overridden at start, as rclpy nodes commonly allow:
        # -p qos_overrides./<namespace>/points.publisher.reliability:=best_effort
        overrides = QoSOverridingOptions(policy_kinds=OVERRIDABLE_POLICIES)
        self._points = node.create_publisher(PointCloud2, POINTS_TOPIC, QUEUE_DEPTH,
                                             qos_overriding_options=overrides)
        self._mesh = node.create_publisher(Marker, MESH_TOPIC, QUEUE_DEPTH,
                                           qos_overriding_options=overrides)
        # each frame's simulation time, whichever clock stamps it (bags/files/sim_time.py)
        self._sim_time = node.create_publisher(TimeReference, SIM_TIME_TOPIC, QUEUE_DEPTH)
        # each change stamped with the simulation time it took effect at (applied_changes.py)
        self._applied = node.create_publisher(ParameterEvent, APPLIED_TOPIC,
                                              QoSPresetProfiles.PARAMETER_EVENTS.value)
        self._diagnostics = node.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC,
                                                  QUEUE_DEPTH)
        self._clock = None  # /clock only when publish_clock asks for it
        self._tf = self._frame_broadcaster(node, scene, values())
        # what the object touches, once and latched (a viewer that comes later has it from the
        # publisher, which is kept for that)
        self._colliders = None
        if scene.contact is not None:
            self._colliders = node.create_publisher(MarkerArray, COLLIDERS_TOPIC, QoSProfile(
                depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
            size = 2.0 * float(np.ptp(np.asarray(scene.rest_positions), axis=0).max())
            self._colliders.publish(collider_markers(
                scene.contact, Header(frame_id=values()['frame_id']), plane_size=size))
        self._announced = False
        if values()['publish_clock']:
            self.enable_clock()

    @staticmethod
    def _frame_broadcaster(node: Node, scene: Scene, values: dict) -> FrameBroadcaster | None:
        """Return the broadcaster of the object's and clamp's frames (None: not broadcast)."""
        if not (values['tf.publish'] and tf_available()):
            return None
        fixed = np.asarray(scene.fixed, dtype=bool)
        centre = (np.asarray(scene.rest_positions, dtype=float)[fixed].mean(axis=0)
                  if fixed.any() else None)
        return FrameBroadcaster(node, values['frame_id'],
                                *broadcast_frames(values, node.get_namespace()), centre)

    def enable_clock(self) -> None:
        """Create the /clock publisher (once; from the executor's thread)."""
        if self._clock is None:
            self._clock = self._node.create_publisher(Clock, CLOCK_TOPIC, QUEUE_DEPTH)

    def frame(self, sim: Simulation, cloud: CloudBuffer, mesh: bool) -> None:
        values = self._values()
        rest = self._scene.rest_positions
        published = self._time.at(sim.time, sim.dt)   # never back: a reset moves it on
        stamp = (to_time_msg(published) if stamps_in_simulation_time(values)
                 else self._node.get_clock().now().to_msg())
        header = Header(stamp=stamp, frame_id=values['frame_id'])
        self._points.publish(cloud.message(header))  # serialised here: the bytes are free again
        self._sim_time.publish(TimeReference(header=header, time_ref=to_time_msg(published),
                                             source=SOURCE))
        if self._tf is not None:
            motion = sim.model.motion.frame(sim.time)
            self._tf.publish(motion.rotation, motion.translation, stamp)
        if self._bag is not None:
            self._capture(lambda: self._bag.cloud_frame(sim.time, cloud))
        if values['publish_clock'] and self._clock is not None:
            self._clock.publish(Clock(clock=to_time_msg(published)))
        if not self._announced:
            self._announced = True
            status = sim.status()
            transport = cloud_transport(cloud.points.nbytes, get_rmw_implementation_identifier(),
                                        share_directory())
            self._node.get_logger().info(
                f'streaming {self._scene.name} ({self._scene.n_particles} particles; '
                f'{status.method}, {status.band}) on '
                f"{self._points.topic_name} at {values['publish_rate_hz']:g} Hz, frame "
                f"'{values['frame_id']}'" + (f'; {transport}' if transport else ''))
        if mesh and self._cells.size and self._mesh.get_subscription_count() > 0:
            self._mesh.publish(mesh_marker(cloud.points[:, :3], rest, self._cells, header,
                                           self._width))

    def _capture(self, write: Callable[[], None]) -> None:
        """
        Write to the capture; if it cannot (a full disk), stop capturing and say so once.

        The stream goes on; what was written stays readable; /diagnostics then reports the
        stop (WARN) for as long as the node runs.
        """
        try:
            write()
        except BagError as exc:
            self.recording_stopped = f'recording stopped: {exc}'
            self._node.get_logger().error(f'{self.recording_stopped}; the stream goes on')
            bag, self._bag = self._bag, None
            with contextlib.suppress(BagError, OSError):
                bag.close()

    def diagnostics(self, status: SimulationStatus, report: StreamReport) -> None:
        if self._bag is not None:  # frames stop while paused: close their chunk
            self._capture(self._bag.writer.flush_if_due)
        if self.recording_stopped:
            report = dataclasses.replace(report, recording=self.recording_stopped)
        self._diagnostics.publish(diagnostic_array(
            status, report, node=self._node.get_fully_qualified_name(),
            hardware_id=self._scene.name, stamp=self._node.get_clock().now().to_msg()))

    def changed(self, sim: Simulation, changed: dict) -> None:
        if not changed:
            return
        published = self._time.at(sim.time, sim.dt)   # as the next frame's (a reset moves it)
        self._applied.publish(parameter_event(published, self._node.get_fully_qualified_name(),
                                              changed))
        if self._bag is not None:
            self._capture(lambda: self._bag.parameter_event(sim.time, changed))

    def received(self, sim: Simulation, recorded: list[tuple[str, Any]]) -> None:
        """Keep an input that took effect at ``sim.time`` in the capture: (topic, message)s."""
        for topic, message in recorded if self._bag is not None else ():
            self._capture(lambda: self._bag.record_input(sim.time, topic, message))

    def log(self, level: str, message: str) -> None:
        logger = self._node.get_logger()
        {'error': logger.error, 'warning': logger.warning, 'info': logger.info}[level](message)

    def close(self) -> None:
        """Finalise the capture, if any (a failure to is logged, as any capture failure)."""
        if self._bag is not None:
            self._capture(self._bag.close)
            self._bag = None

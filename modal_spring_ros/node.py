"""``modal_spring_node``: steps the modal simulation and streams it as ``sensor_msgs/PointCloud2``.

A thin ROS layer over the engine. A dedicated simulation thread steps at a fixed ``sim.dt`` and
publishes on its own period (``publish_rate_hz``), so the stream stays steady while the
executor thread serves parameter and service requests. Every change is validated in the
parameter callback (computing missing modes there; on large scenes in a worker process, so
that the stream goes on meanwhile) and handed to the simulation thread, which applies it
between two steps.

Topics (relative names, so namespaces and remapping work): ``points`` (PointCloud2), ``mesh``
(Marker TRIANGLE_LIST, for scenes with a surface, when subscribed), ``/diagnostics``, and
``/clock`` when ``publish_clock`` is true. Services: ``~/reset`` (Trigger), ``~/pause``
(SetBool). See README.md for every parameter.
"""
from __future__ import annotations

import dataclasses
import math
import queue
import signal
import sys
import threading
import time
from typing import Any, Callable

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                ParameterType, SetParametersResult)
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import ColorRGBA, Header
from std_srvs.srv import SetBool, Trigger
from visualization_msgs.msg import Marker

from modal_spring_ros.bag_writer import BagError
from modal_spring_ros.filter_band import FILTER_TYPES, UNITS, BandError, FilterBand
from modal_spring_ros.newmark import INTEGRATORS
from modal_spring_ros.pointcloud import distance_from_rest, to_pointcloud2
from modal_spring_ros.ros_time import to_time_msg
from modal_spring_ros.scene import DEFAULT_SCENE, SceneError
from modal_spring_ros.simulation import METHODS, DivergenceError, ModalSimulation, Simulation
from modal_spring_ros.simulation_factory import (SimulationConfig, UnstableStepError,
                                                 build_simulation, check_band, check_stable,
                                                 config_from_parameters, rebuild,
                                                 REBUILD_PARAMETERS)
from modal_spring_ros.worker_process import WorkerError, WorkerProcess

NODE_NAME = "modal_spring"
#: Topics (relative, so that namespaces and remapping apply); diagnostics and clock are global.
POINTS_TOPIC = "points"
MESH_TOPIC = "mesh"
#: Largest spring strain still in the small-deformation regime the modal basis assumes.
DEFAULT_STRAIN_WARNING = 0.1
DIAGNOSTICS_PERIOD_S = 1.0
#: Achieved real-time factor below this share of the requested one is reported.
REALTIME_TOLERANCE = 0.9
#: A gap between frames longer than this many publish periods is reported as a stall.
STALL_PERIODS = 3.0


def _descriptor(description: str, type_: int, *, read_only: bool = False,
                float_range: tuple[float, float] | None = None,
                int_range: tuple[int, int] | None = None,
                constraints: str = "") -> ParameterDescriptor:
    d = ParameterDescriptor(description=description, type=type_, read_only=read_only,
                            additional_constraints=constraints)
    if float_range is not None:
        d.floating_point_range = [FloatingPointRange(from_value=float_range[0],
                                                     to_value=float_range[1], step=0.0)]
    if int_range is not None:
        d.integer_range = [IntegerRange(from_value=int_range[0], to_value=int_range[1], step=1)]
    return d


_D, _S, _I, _B = (ParameterType.PARAMETER_DOUBLE, ParameterType.PARAMETER_STRING,
                  ParameterType.PARAMETER_INTEGER, ParameterType.PARAMETER_BOOL)

#: name -> (default, descriptor). Band edges carry no descriptor range: the callback checks
#: them (finite, non-negative, low < high) and says so by name.
PARAMETERS: dict[str, tuple[Any, ParameterDescriptor]] = {
    "scene": (DEFAULT_SCENE, _descriptor(
        "Built-in scene name or path of a scene YAML file", _S, read_only=True)),
    "method": ("modal", _descriptor(
        "modal: step only the modes the filter keeps; full: every DOF in physical coordinates",
        _S, constraints="one of " + ", ".join(METHODS))),
    "filter.type": ("allpass", _descriptor(
        "Which modes take part", _S, constraints="one of " + ", ".join(FILTER_TYPES))),
    "filter.by": ("hz", _descriptor(
        "Band edges in Hz (filter.low_hz/high_hz) or as zero-based mode numbers "
        "(filter.low_mode/high_mode)", _S, constraints="hz or index")),
    "filter.low_hz": (0.0, _descriptor(
        "Lower band edge, Hz (highpass, bandpass, bandstop)", _D,
        constraints="finite, >= 0, below filter.high_hz")),
    "filter.high_hz": (1000.0, _descriptor(
        "Upper band edge, Hz (lowpass, bandpass, bandstop)", _D,
        constraints="finite, >= 0, above filter.low_hz")),
    "filter.low_mode": (0, _descriptor(
        "Lower band edge as a mode number (filter.by = index)", _I, int_range=(0, 1_000_000))),
    "filter.high_mode": (14, _descriptor(
        "Upper band edge as a mode number (filter.by = index)", _I, int_range=(0, 1_000_000))),
    "filter.transition_s": (0.5, _descriptor(
        "Fade time of modes leaving or entering the band, s", _D, float_range=(0.0, 60.0))),
    "integrator": ("explicit", _descriptor(
        "Newmark member: explicit (beta 0, the paper's) or average (beta 1/4, implicit)", _S,
        constraints="one of " + ", ".join(INTEGRATORS))),
    "sim.dt": (0.0, _descriptor(
        "Simulation step, s; 0 = the scene's, else half the explicit stability limit", _D,
        float_range=(0.0, 1.0))),
    "sim.strain_limit": (1.0, _descriptor(
        "Spring strain treated as divergence", _D, read_only=True, float_range=(0.001, 100.0))),
    "sim.strain_warning": (DEFAULT_STRAIN_WARNING, _descriptor(
        "Spring strain above which the small-deformation basis is reported as strained (WARN)",
        _D, float_range=(0.0, 100.0))),
    "publish_rate_hz": (60.0, _descriptor(
        "Rate of points (and clock) messages, Hz", _D, float_range=(0.1, 1000.0))),
    "mesh_rate_hz": (10.0, _descriptor(
        "Rate of mesh markers, Hz (only while someone subscribes)", _D,
        float_range=(0.0, 1000.0))),
    "realtime_factor": (1.0, _descriptor(
        "Simulated seconds per wall second; 0 = as fast as possible", _D,
        float_range=(0.0, 1000.0))),
    "frame_id": ("world", _descriptor("header.frame_id of points and mesh", _S)),
    "stamp": ("sim", _descriptor(
        "header.stamp of points and mesh: sim (simulation time, as /clock) or wall (the "
        "node's clock when publishing, for latency measurement or wall-time TF)", _S,
        constraints="sim or wall")),
    "publish_clock": (False, _descriptor("Publish simulation time on /clock", _B)),
    "modal.auto": (False, _descriptor(
        "Keep the fewest modes (within the band) that meet modal.tolerance for the scene's "
        "loads (gravity, anchor motion), and the step they allow unless sim.dt is set", _B)),
    "modal.tolerance": (0.01, _descriptor(
        "Predicted relative error the automatic mode choice must meet", _D,
        float_range=(1e-6, 0.5))),
    "modal.force_refresh": (0, _descriptor(
        "Steps between exact evaluations of the nonlinear spring forces (1 = every step, as "
        "the paper; N > 1 continues them along the static tangent in between); 0 = every "
        "step, or what modal.auto chooses", _I, int_range=(0, 10_000))),
    "record.bag": ("", _descriptor(
        "If set, a new bag folder that every published frame is written to directly (no DDS), "
        "with the scene, the parameters and every change: re-simulates exactly", _S,
        read_only=True)),
    "modal.max_modes": (256, _descriptor(
        "Most modes computed on scenes too large for a dense eigensolver", _I, read_only=True,
        int_range=(1, 100_000))),
}

STAMPS = ("sim", "wall")

BAND = {"filter.type", "filter.by", "filter.low_hz", "filter.high_hz", "filter.low_mode",
        "filter.high_mode", "filter.transition_s"}


CHOICES = {"method": METHODS, "filter.type": FILTER_TYPES, "filter.by": UNITS,
           "integrator": INTEGRATORS, "stamp": STAMPS}


def _format_refresh_error(sim) -> str:
    """Largest measured error of the refreshed spring forces, or why there is none."""
    error = getattr(sim, "refresh_error", None)
    return "exact every step" if error is None else f"{error:.2e}"


def check_choices(values: dict[str, Any]) -> None:
    """Raise ValueError naming the first string parameter whose value is not allowed."""
    for name, allowed in CHOICES.items():
        if values[name] not in allowed:
            raise ValueError(f"{name} '{values[name]}' must be one of {', '.join(allowed)}")


@dataclasses.dataclass
class _Stats:
    """Simulation-thread bookkeeping for /diagnostics (written by that thread only)."""

    step_seconds: float = 0.0
    steps: int = 0
    frames: int = 0
    window_wall: float = 0.0
    window_sim: float = 0.0
    achieved_rtf: float = 0.0
    window_valid: bool = True  # no reset, pause or rebuild inside the window
    last_publish: float = 0.0
    longest_gap: float = 0.0   # longest time between two frames in the window, s
    stall_while_computing: bool = False
    divergences: int = 0
    last_divergence: str = ""
    diverged_recently: bool = False


class ModalSpringNode(Node):
    """Streams a scene's filtered deformation. Construct, spin, then :meth:`stop`."""

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        for name, (default, descriptor) in PARAMETERS.items():
            self.declare_parameter(name, default, descriptor)
        self._values = {name: self.get_parameter(name).value for name in PARAMETERS}
        log = self.get_logger()
        check_choices(self._values)
        config = self._config(self._values)
        config.band.validate()
        # Sparse mode computations (large scenes) run in a worker process, so that they never
        # hold this process's interpreter lock while the stream runs; shutting down (Ctrl-C)
        # cancels them.
        self._worker = WorkerProcess("modal_spring_modes",
                                     cancelled=lambda: not self.context.ok())
        try:
            self.sim: Simulation = build_simulation(self._values["scene"], config,
                                                    progress=lambda msg: log.info(msg),
                                                    worker=self._worker)
        except BaseException:
            self._worker.close()
            raise
        self.model = self.sim.model
        self.basis = self.sim.basis
        scene = self.model.scene
        # A modal probe to validate bands while the full method runs.
        self._modal_probe = self.sim if isinstance(self.sim, ModalSimulation) else None
        self._triangles = scene.surface_triangles()
        self.declare_parameter("modal.frequencies_hz", self.basis.frequencies_hz.tolist(),
                               _descriptor("Frequencies of the computed modes, Hz (ascending)",
                                           ParameterType.PARAMETER_DOUBLE_ARRAY,
                                           read_only=True))
        self._points_pub = self.create_publisher(PointCloud2, POINTS_TOPIC, 10)
        self._mesh_pub = self.create_publisher(Marker, MESH_TOPIC, 10)
        self._diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._clock_pub = self.create_publisher(Clock, "/clock", 10)
        self.create_service(Trigger, "~/reset", self._on_reset)
        self.create_service(SetBool, "~/pause", self._on_pause)
        self._requests: queue.Queue[tuple[str, Any, threading.Event | None]] = queue.Queue()
        self._lock = threading.Lock()  # guards parameter validation (one change at a time)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._paused = False
        self._reanchor = False
        self._computing_modes = False  # a parameter request is computing modes
        self._stats = _Stats()
        self._stop = threading.Event()
        log.info(f"scene {scene.name}: {scene.n_particles} particles, "
                 f"{self.basis.count} modes computed; {self._describe()}; dt {self.sim.dt:g} s")
        self._bag = None
        if self._values["record.bag"]:
            from modal_spring_ros.run_bag import RunBagWriter
            self._bag = RunBagWriter(
                self._values["record.bag"], scene, None, dt=self.sim.dt, frame_every=0,
                duration=0.0, frame_id=self._values["frame_id"], source="modal_spring_node",
                parameters={k: v for k, v in self._values.items()},
                node=self.get_fully_qualified_name())
            log.info(f"writing every frame to {self._values['record.bag']}")
        self._thread = threading.Thread(target=self._run, name="modal_spring_sim", daemon=True)
        self._thread.start()

    # -- configuration -------------------------------------------------------------------------
    _config = staticmethod(config_from_parameters)

    def _describe(self) -> str:
        sim = self.sim
        if isinstance(sim, ModalSimulation):
            return f"modal, {sim.band.describe()}, {sim.kept_modes.size} modes stepped"
        return f"full, {self.model.n_free_dof} DOF"

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        incoming = {p.name: p.value for p in params if p.name in PARAMETERS}
        if not incoming:
            return SetParametersResult(successful=True)
        with self._lock:
            try:
                self._validate_and_queue(incoming)
            except (BandError, UnstableStepError, ValueError, SceneError, WorkerError) as exc:
                self.get_logger().warning(f"parameter change rejected: {exc}")
                return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _validate_and_queue(self, incoming: dict[str, Any]) -> None:
        values = dict(self._values, **incoming)
        check_choices(values)
        for name in ("filter.low_hz", "filter.high_hz"):
            v = float(values[name])
            if not math.isfinite(v):
                raise BandError(f"{name} ({v}) must be finite")
            if v < 0:
                raise BandError(f"{name} ({v:g}) must not be negative")
        if not values["frame_id"]:
            raise ValueError("frame_id must not be empty")
        config = self._config(values)
        band = config.band.validate()
        changed = {name for name, value in incoming.items() if value != self._values[name]}
        new_sim = None
        if changed & REBUILD_PARAMETERS:
            new_sim = self._rebuilt(config)
            if isinstance(new_sim, ModalSimulation):
                check_band(new_sim, band, "sim.dt")
        elif changed & BAND:
            probe = self._probe(config)
            self._computing_modes = True
            try:
                check_band(probe, band, "sim.dt")
                if probe is self.sim:  # build the switch here, not in the stepping thread
                    probe.prepare_switch(band, config.transition_s)
            finally:
                self._computing_modes = False
        self._publish_frequencies()
        self._values = values
        delta = {name: values[name] for name in changed}
        if new_sim is not None:
            self._requests.put(("simulation", (new_sim, delta), None))
        elif changed & BAND:
            self._requests.put(("band", (band, config.transition_s, delta), None))

    def _probe(self, config: SimulationConfig) -> ModalSimulation:
        """A modal simulation to check bands against (the running one when modal)."""
        if isinstance(self.sim, ModalSimulation):
            return self.sim
        if self._modal_probe is None or self._modal_probe.dt != self.sim.dt:
            self._modal_probe = ModalSimulation(self.model, self.basis, FilterBand(),
                                                dt=self.sim.dt, integrator=config.integrator,
                                                max_modes=config.max_modes)
        return self._modal_probe

    def _rebuilt(self, config: SimulationConfig) -> Simulation:
        sim = rebuild(self.model, self.basis, config)
        check_stable(sim, "sim.dt")
        return sim

    def _publish_frequencies(self) -> None:
        """Refresh the read-only modal.frequencies_hz when more modes were computed."""
        name = "modal.frequencies_hz"
        freqs = self.basis.frequencies_hz.tolist()
        if len(freqs) == len(self.get_parameter(name).value):
            return
        # Read-only for users; the node itself updates it with its own descriptor.
        setter = getattr(self, "_set_parameters_atomically_common", None)
        if setter is not None:
            setter([Parameter(name, value=freqs)],
                   descriptors={name: self.describe_parameter(name)})

    # -- services ------------------------------------------------------------------------------
    def _request(self, kind: str, payload: Any = None, timeout: float = 2.0) -> bool:
        done = threading.Event()
        self._requests.put((kind, payload, done))
        return done.wait(timeout)

    def _on_reset(self, _req, response):
        response.success = self._request("reset")
        response.message = ("back to the rest state at t = 0" if response.success
                            else "reset did not complete in time")
        return response

    def _on_pause(self, request, response):
        response.success = self._request("pause", bool(request.data))
        response.message = ("paused" if request.data else "running") if response.success \
            else "pause did not complete in time"
        return response

    # -- simulation thread ---------------------------------------------------------------------
    def _apply_requests(self) -> bool:
        """Apply queued changes between steps; True when the time base must be re-anchored."""
        reanchor = False
        while True:
            try:
                kind, payload, done = self._requests.get_nowait()
            except queue.Empty:
                return reanchor
            try:
                if kind == "band":
                    band, transition, delta = payload
                    if isinstance(self.sim, ModalSimulation):
                        self.sim.set_band(band, transition)
                    self._record_change(delta)
                elif kind == "simulation":
                    new_sim, delta = payload
                    new_sim.take_over(self.sim)
                    self.sim = new_sim
                    self._record_change(delta)
                    reanchor = True
                elif kind == "reset":
                    self.sim.reset()
                    reanchor = True
                elif kind == "pause":
                    self._paused = payload
                    reanchor = True
            except (BandError, ValueError) as exc:  # e.g. basis changed meanwhile
                self.get_logger().error(f"could not apply {kind}: {exc}")
            finally:
                if done is not None:
                    done.set()

    def _record_change(self, delta: dict) -> None:
        if self._bag is not None and delta:
            self._bag.parameter_event(self.sim.time, delta)

    def _run(self) -> None:
        try:
            self._loop()
        except Exception as exc:
            if self._stop.is_set() or not self.context.ok():
                return  # shutting down: publishers may already be gone
            # never die silently: report and stop the stream
            self.get_logger().fatal(f"simulation thread failed: {exc!r}")
            self._publish_diagnostics(error=f"simulation thread failed: {exc!r}")

    def _loop(self) -> None:
        st = self._stats
        wall_anchor = time.monotonic()
        sim_anchor = self.sim.time
        next_publish = wall_anchor
        next_mesh = wall_anchor
        next_diag = wall_anchor + DIAGNOSTICS_PERIOD_S
        st.window_wall, st.window_sim = wall_anchor, self.sim.time
        published_time = None
        while not self._stop.is_set() and self.context.ok():
            period = 1.0 / self._values["publish_rate_hz"]
            rtf = self._values["realtime_factor"]
            if self._apply_requests():
                wall_anchor, sim_anchor = time.monotonic(), self.sim.time
                published_time = None
                st.window_valid = False
            deadline = next_publish + period
            if not self._paused:
                if rtf > 0.0:
                    target = sim_anchor + (time.monotonic() - wall_anchor) * rtf
                    self._step_until(lambda: self.sim.time + 0.5 * self.sim.dt >= target,
                                     deadline)
                    if self.sim.time + self.sim.dt < target:  # could not keep up: drop debt
                        wall_anchor, sim_anchor = time.monotonic(), self.sim.time
                else:
                    self._step_until(lambda: False, next_publish)
            if self._reanchor:
                self._reanchor = False
                st.window_valid = False
                wall_anchor, sim_anchor = time.monotonic(), self.sim.time
            now = time.monotonic()
            if self.sim.time != published_time and not self._paused:
                self._publish_frame(mesh=now >= next_mesh)
                published_time = self.sim.time
                if now >= next_mesh and self._values["mesh_rate_hz"] > 0:
                    next_mesh = now + 1.0 / self._values["mesh_rate_hz"]
            if now >= next_diag:
                self._publish_diagnostics()
                next_diag = now + DIAGNOSTICS_PERIOD_S
            next_publish += period
            if next_publish < now:
                next_publish = now + period
            self._stop.wait(max(0.0, next_publish - time.monotonic()))

    def _step_until(self, done: Callable[[], bool], deadline: float) -> None:
        st = self._stats
        while not done():
            start = time.perf_counter()
            try:
                self.sim.step()
            except DivergenceError as exc:
                self._on_divergence(exc)
                return
            st.step_seconds += time.perf_counter() - start
            st.steps += 1
            if time.monotonic() > deadline:
                return

    def _on_divergence(self, exc: DivergenceError) -> None:
        st = self._stats
        st.divergences += 1
        st.last_divergence = str(exc)
        st.diverged_recently = True
        self.get_logger().error(f"{exc}; back to the rest state")
        self._publish_diagnostics(error=f"{exc}; recovered: back to the rest state")
        self.sim.reset()
        self._reanchor = True

    def _publish_frame(self, mesh: bool) -> None:
        positions = self.sim.positions()
        if not np.isfinite(positions).all():  # defensive: the engine never returns these
            self._on_divergence(DivergenceError("non-finite positions", self.sim.time,
                                                self.sim.steps))
            return
        stamp = (to_time_msg(self.sim.time) if self._values["stamp"] == "sim"
                 else self.get_clock().now().to_msg())
        header = Header(stamp=stamp, frame_id=self._values["frame_id"])
        self._points_pub.publish(to_pointcloud2(positions, self.model.scene.rest_positions,
                                                header))
        st = self._stats
        now = time.monotonic()
        if st.last_publish:
            st.longest_gap = max(st.longest_gap, now - st.last_publish)
        st.last_publish = now
        st.frames += 1
        if self._bag is not None:
            self._bag.frame(self.sim.time, positions)
        if self._values["publish_clock"]:
            self._clock_pub.publish(Clock(clock=to_time_msg(self.sim.time)))
        if (mesh and self._triangles.size and self._values["mesh_rate_hz"] > 0
                and self._mesh_pub.get_subscription_count() > 0):
            self._mesh_pub.publish(self._mesh_marker(positions, header))

    def _mesh_marker(self, positions: np.ndarray, header: Header) -> Marker:
        corners = positions[self._triangles.ravel()]
        disp = distance_from_rest(corners,
                                  self.model.scene.rest_positions[self._triangles.ravel()])
        level = np.clip(disp / max(float(disp.max()), 1e-12), 0.0, 1.0)
        m = Marker(header=header, ns="modal_spring", id=0, type=Marker.TRIANGLE_LIST,
                   action=Marker.ADD)
        m.pose.orientation.w = 1.0
        m.scale.x = m.scale.y = m.scale.z = 1.0
        m.points = [Point(x=x, y=y, z=z) for x, y, z in corners.tolist()]
        m.colors = [ColorRGBA(r=c, g=0.2, b=1.0 - c, a=1.0) for c in level.tolist()]
        return m

    def _publish_diagnostics(self, error: str | None = None) -> None:
        st = self._stats
        sim = self.sim
        now = time.monotonic()
        if now > st.window_wall and st.window_valid:
            st.achieved_rtf = (sim.time - st.window_sim) / (now - st.window_wall)
        strain = sim.max_strain()
        level, message = DiagnosticStatus.OK, "streaming"
        requested = self._values["realtime_factor"]
        if self._paused:
            message = "paused"
        elif (st.window_valid and requested > 0
              and st.achieved_rtf < REALTIME_TOLERANCE * requested):
            level = DiagnosticStatus.WARN
            message = (f"cannot keep real time: achieved real-time factor "
                       f"{st.achieved_rtf:.2f} of {requested:g}")
        period = 1.0 / self._values["publish_rate_hz"]
        if st.longest_gap > STALL_PERIODS * period and not self._paused:
            level = DiagnosticStatus.WARN
            message = (f"stream stalled for {st.longest_gap:.2f} s"
                       + (" while computing modes for a band change"
                          if self._computing_modes or st.stall_while_computing else ""))
        if strain > self._values["sim.strain_warning"]:
            level = DiagnosticStatus.WARN
            message = (f"large deformation: spring strain {strain:.1%} beyond the "
                       f"small-deformation regime of the modal basis")
        if error or st.diverged_recently:
            level = DiagnosticStatus.ERROR
            message = error or f"{st.last_divergence}; recovered: back to the rest state"
        kept = sim.kept_modes.size if isinstance(sim, ModalSimulation) else self.model.n_free_dof
        values = {
            "method": sim.method,
            "band": sim.band.describe() if isinstance(sim, ModalSimulation) else "full",
            "modes stepped": str(kept),
            "modes computed": str(self.basis.count),
            "automatic mode choice": sim.auto.describe() if getattr(sim, "auto", None)
            else "off",
            "integrator": sim.integrator,
            "dt (s)": f"{sim.dt:g}",
            "force refresh (steps)": str(getattr(sim, "force_refresh", 1)),
            "force refresh error": _format_refresh_error(sim),
            "stability limit (s)": f"{sim.stability_limit():.4g}",
            "step time (us)": f"{1e6 * st.step_seconds / max(st.steps, 1):.1f}",
            "requested real-time factor": f"{requested:g}",
            "achieved real-time factor": f"{st.achieved_rtf:.3f}",
            "simulation time (s)": f"{sim.time:.3f}",
            "frames published": str(st.frames),
            "largest spring strain": f"{strain:.5f}",
            "divergence": st.last_divergence or "none",
            "divergences": str(st.divergences),
            "paused": str(self._paused).lower(),
            "longest gap between frames (s)": f"{st.longest_gap:.3f}",
            "computing modes": str(self._computing_modes).lower(),
        }
        status = DiagnosticStatus(
            level=level, name=f"{self.get_fully_qualified_name()}: simulation",
            message=message, hardware_id=self.model.scene.name,
            values=[KeyValue(key=k, value=v) for k, v in values.items()])
        self._diag_pub.publish(DiagnosticArray(header=Header(stamp=self.get_clock().now().to_msg()),
                                               status=[status]))
        st.step_seconds, st.steps = 0.0, 0
        st.window_wall, st.window_sim = now, sim.time
        st.window_valid = True
        st.longest_gap = 0.0
        st.stall_while_computing = self._computing_modes
        if not error:
            st.diverged_recently = False

    def stop(self) -> None:
        """Stop the simulation thread (before destroy_node) and finalise the bag, if any."""
        self._stop.set()
        self._worker.close()
        if self._thread.is_alive():
            self._thread.join(timeout=5.0)
        if self._bag is not None:
            self._bag.close()
            self._bag = None


def _ignore_after_rclpy(signum, frame) -> None:
    """rclpy's SIGTERM handler shuts the context down and then chains to the previous
    handler; with this one (instead of the default, which kills the process) spin returns and
    the node ends as cleanly as on SIGINT."""


def main(args: list[str] | None = None) -> int:
    signal.signal(signal.SIGTERM, _ignore_after_rclpy)
    rclpy.init(args=args)
    node = None
    try:
        node = ModalSpringNode()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (SceneError, BandError, UnstableStepError, ValueError, ParameterException,
            BagError) as exc:
        print(f"modal_spring_node: error: {exc}", file=sys.stderr)
        return 2
    except Exception as exc:
        if not rclpy.ok():
            return 0  # interrupted while starting (say, during a long mode computation)
        if isinstance(exc, WorkerError):
            print(f"modal_spring_node: error: computing the modes failed: {exc}",
                  file=sys.stderr)
            return 1
        raise
    finally:
        if node is not None:
            node.stop()
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())

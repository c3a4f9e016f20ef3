"""
``modal_spring_node``: steps the modal simulation and streams it as ``sensor_msgs/PointCloud2``.

Wiring only. The simulation thread (:mod:`~modal_spring_ros.ros.stream.simulation_thread`) steps at
a fixed ``sim.dt`` and publishes on its own period (:mod:`~modal_spring_ros.ros.stream.outputs`).
The executor serves parameter requests (:mod:`~modal_spring_ros.ros.changes.node_parameters`; their
slow part is prepared off the services' thread,
:mod:`~modal_spring_ros.ros.changes.change_preparer`) and ``~/reset``, ``~/pause`` and ``~/step``,
awaited without holding an executor thread; every change reaches the simulation thread as one
request (:mod:`~modal_spring_ros.ros.changes.requests`); large scenes stream before all is prepared
(:mod:`~modal_spring_ros.ros.start.start_up`).

Topics (relative names, so namespaces and remapping work): ``points`` (PointCloud2), ``mesh``
(Marker: the surface's triangles, or the springs' lines, when subscribed), ``/diagnostics``,
``/tf`` (the object's and the clamp's frames, :mod:`~modal_spring_ros.ros.frames.tf`), and
``/clock`` when ``publish_clock`` is true. Subscriptions
(:mod:`~modal_spring_ros.ros.inputs.subscriptions`, on the companion node ``<name>_inputs``,
:mod:`~modal_spring_ros.ros.inputs.input_node`): ``anchor_pose`` (PoseStamped, with
``anchor.source`` topic), ``/clicked_point`` (PointStamped), ``wrench`` (WrenchStamped), ``/tf``
and ``/tf_static``. Services: ``~/reset`` (Trigger), ``~/pause`` (SetBool), ``~/step`` (Trigger,
while paused), and ROS 2's standard simulation services (``~/step_simulation``,
``~/set_simulation_state``, ``~/get_simulation_state``, ``~/reset_simulation``,
``~/get_simulator_features``). See docs/node.md.
"""
from __future__ import annotations

from modal_spring_ros.bags.files.capture import RunBagWriter
from modal_spring_ros.core.config import POSE_SOURCES
from modal_spring_ros.core.factory import build_simulation, rebuild
from modal_spring_ros.core.memory_estimate import check_run_memory
from modal_spring_ros.core.worker import WorkerProcess
from modal_spring_ros.ros.changes.node_parameters import NodeParameters
from modal_spring_ros.ros.changes.parameter_changes import ChangePlanner
from modal_spring_ros.ros.changes.run_services import RunServices
from modal_spring_ros.ros.frames.tf import tf_available
from modal_spring_ros.ros.inputs.input_node import InputNode, TF_CPU_SHARE, TF_MAX_RATE_HZ
from modal_spring_ros.ros.inputs.subscriptions import NodeInputs
from modal_spring_ros.ros.parameters import (CLOCK_OFFSET, CLOCK_OFFSET_DESCRIPTOR,
                                             config_from_parameters, FREQUENCIES,
                                             FREQUENCIES_DESCRIPTOR, PARAMETERS)
from modal_spring_ros.ros.process.namesakes import count_namesakes, namesakes_warning
from modal_spring_ros.ros.process.stop_signals import StopSignals
from modal_spring_ros.ros.start.start_up import first_values
from modal_spring_ros.ros.start.start_up_report import StartUpReport
from modal_spring_ros.ros.stream.outputs import NodeOutputs
from modal_spring_ros.ros.stream.plan_watch import fall_back
from modal_spring_ros.ros.stream.run_pace import pace_reading
from modal_spring_ros.ros.stream.simulation_thread import SimulationThread
from modal_spring_ros.ros.stream.stream_settings import StreamSettings
from modal_spring_ros.ros.stream.stream_time import clock_warnings, StreamTime
from modal_spring_ros.runs.sample_cache import sample_cache
from modal_spring_ros.scenes.fields.limits import available_memory
from modal_spring_ros.scenes.resources import load_scene
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.parameter import Parameter

NODE_NAME = 'modal_spring'
#: how often the graph is searched for other nodes of this node's name, s
NAMESAKE_CHECK_S = 2.0
#: the node's parts, stopped in this order (inputs first, the capture last), as attribute and
#: method names: a node stopped while it starts stops the parts it has
STOP_ORDER = (('_input_node', 'close'), ('_tf_node', 'close'), ('_preparer', 'stopping'),
              ('_worker', 'close'),
              ('_preparer', 'stop'), ('_thread', 'stop'), ('_outputs', 'close'))


class ModalSpringNode(Node):
    """Streams a scene's filtered deformation. Construct, spin, then :meth:`stop`."""

    def __init__(self, stop: StopSignals | None = None, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        # what ends the run: the process's stop signals (set before ROS is shut down), or ROS
        self._stop = stop or StopSignals()
        try:
            self._start()
        except BaseException:
            # a failure or a Ctrl-C while starting: what started is stopped and the node
            # destroyed here (no thread left running into the interpreter's exit)
            self.stop()
            self.destroy_node()
            raise

    def _start(self) -> None:
        self._declare_parameters()
        self._build()
        self._begin()

    def _declare_parameters(self) -> None:
        for name, (default, descriptor) in PARAMETERS.items():
            self.declare_parameter(name, default, descriptor)

    def _build(self) -> None:
        """Build the run and every part of the node from the parameters; start no thread."""
        values = {name: self.get_parameter(name).value for name in PARAMETERS}
        log = self.get_logger()
        # large scenes' modes and samples: in a worker process (never this interpreter's lock)
        self._worker = WorkerProcess('modal_spring_modes', cancelled=lambda: not self._running())
        scene = load_scene(values['scene'], log.info)
        asked = config_from_parameters(values)
        check_run_memory(scene, asked, available_memory())     # the run it settles on
        first = first_values(asked, scene) if values['stream_early'] else {}
        self._progress = StartUpReport(self, scene.name)
        with self._progress:    # on /diagnostics until the run streams
            sim = build_simulation(scene, config_from_parameters(dict(values, **first)),
                                   progress=self._progress.progress, worker=self._worker,
                                   samples=sample_cache())
        sim.check_stable('sim.dt')
        self._params = NodeParameters(
            self, ChangePlanner(sim.model, sim.basis), running=lambda: self._thread.sim,
            submit=lambda request: self._thread.submit(request),
            settings_changed=lambda: self._thread.settings_changed(),
            enable_clock=lambda: self._outputs.enable_clock())
        self._preparer = self._params.preparer
        self._params.start_from(first)
        # published time goes on from where it was (a managed node configured again)
        self._time = StreamTime(getattr(self, '_time', StreamTime()).reached,
                                moved=lambda offset: self._params.report(CLOCK_OFFSET, offset))
        self._report_parameter(FREQUENCIES, sim.basis.frequencies_hz.tolist(),
                               FREQUENCIES_DESCRIPTOR)
        self._report_parameter(CLOCK_OFFSET, self._time.offset, CLOCK_OFFSET_DESCRIPTOR)
        scene = sim.model.scene     # as the run has it (a loaded shape)
        self._outputs = NodeOutputs(self, scene, lambda: self._params.values,
                                    self._open_capture(sim), self._time)
        self._thread = SimulationThread(
            sim, self._outputs, self._stream_settings, rebuild=lambda: rebuild(
                sim.model, sim.basis, config_from_parameters(self._params.applied())),
            computing_modes=lambda: self._preparer.busy, running=self._running,
            node_report=self._report, pace=lambda: pace_reading(
                self.get_clock(), self._params.values['publish_clock']),
            on_watch_beyond=lambda window, plan: fall_back(self, window, plan, self._running))
        self._params.listen()
        follower = sim.model.motion if values['anchor.source'] in POSE_SOURCES else None
        self._input_node = InputNode(self)      # its own thread: a flood never starves the run
        self._tf_node = (InputNode(self, TF_MAX_RATE_HZ, TF_CPU_SHARE, suffix='tf')
                         if tf_available() else None)   # TF on its own: it keeps up
        self._inputs = NodeInputs(self._input_node.node, follower, lambda: self._params.values,
                                  self._thread.submit,
                                  tf_node=self._tf_node.node if self._tf_node else None,
                                  contact=scene.contact)
        self._run_services = RunServices(  # the thread's submit looked up per call
            self, lambda request: self._thread.submit(request), lambda: self._thread.paused,
            lambda: self._thread.sim.time == 0.0)
        steady = Clock(clock_type=ClockType.STEADY_TIME)    # wall time, even under use_sim_time
        self._namesakes = 0
        self.create_timer(NAMESAKE_CHECK_S, self._check_namesakes, clock=steady)
        status = sim.status()
        log.info(f'scene {scene.name}: {scene.n_particles} particles, {status.modes_computed} '
                 f'modes computed; {status.method}, {status.band}, {status.coordinates} '
                 f"{'modes' if status.method == 'modal' else 'DOF'} stepped; dt {sim.dt:g} s")
        for warning in clock_warnings(self.get_parameter('use_sim_time').value, values):
            log.warning(warning)

    def _report_parameter(self, name: str, value, descriptor) -> None:
        """Declare a parameter the node reports, or set it when built again (before listening)."""
        if self.has_parameter(name):
            self.set_parameters([Parameter(name, value=value)])
        else:
            self.declare_parameter(name, value, descriptor)

    def _begin(self) -> None:
        """Start streaming (the simulation and inputs' threads); then prepare what waited."""
        for part in (self._thread, self._input_node, self._tf_node):
            if part is not None:
                part.start()
        self._worker.give_way()     # its long work gives way to the stream from now on
        self._params.prepare_asked()

    def _running(self) -> bool:
        return self._stop.running(self.context)

    @property
    def sim(self):
        """Return the running simulation (owned by the simulation thread: read, never change)."""
        return self._thread.sim

    def _open_capture(self, sim) -> RunBagWriter | None:
        values = self._params.values
        applied = self._params.applied()    # what runs (the values asked for come as changes)
        path = values['record.bag']
        if not path:
            return None
        # a managed node configured again (after cleanup) keeps its first capture: the next
        # ones go beside it, numbered as rosbag2 numbers a bag's files
        self._captures = getattr(self, '_captures', 0) + 1
        path = path if self._captures == 1 else f'{path}_{self._captures}'
        bag = RunBagWriter(path, sim.model.scene, None, dt=sim.dt, frame_every=0, duration=0.0,
                           frame_id=values['frame_id'], source='modal_spring_node',
                           parameters=applied, node=self.get_fully_qualified_name())
        self.get_logger().info(f'writing every frame to {path}')
        return bag

    def _stream_settings(self) -> StreamSettings:
        v = self._params.values
        return StreamSettings(v['publish_rate_hz'], v['mesh_rate_hz'], v['realtime_factor'],
                              v['sim.strain_warning'], v['modal.watch'])

    def _report(self) -> dict:
        """Return what the node adds to the simulation thread's report on /diagnostics."""
        anchor, stale = self._inputs.anchor_status()
        state = self._preparer.state()
        return {'anchor': anchor, 'anchor_stale': stale,
                'parameters_preparing': state.preparing, 'parameters_reverted': state.reverted,
                'progress': self._progress.latest(state.since) if state.preparing else '',
                'namesakes': self._namesakes, 'name': self.get_fully_qualified_name()}

    def _check_namesakes(self) -> None:
        found = count_namesakes(self)
        if found > 0 and found != self._namesakes:   # once per change
            self.get_logger().warning(namesakes_warning(found, self.get_fully_qualified_name()))
        self._namesakes = found

    def stop(self) -> None:
        """Stop the threads (before destroy_node) and finalise the capture; whatever started."""
        for name, method in STOP_ORDER:
            part = getattr(self, name, None)
            if part is not None:
                getattr(part, method)()

"""
Re-run the simulation a bag recorded and write its frames to a new bag.

A bag written by ``modal_spring_sim --bag`` describes its run completely (scene, settings,
frame spacing), and so does the node's own capture (``record.bag``: parameters at the start,
each change and each input it followed (poses, clicked points) stamped with the simulation
time it took effect at): re-simulating either reproduces every frame to float32 round-off.
A bag recorded over DDS by ``modal_spring_record`` holds the scene, the node's parameters at
the start, every later change as received on ``/parameter_events``, and each change again on
``applied_parameter_events`` stamped with the simulation time the node applied it at
(``bags/files/applied_changes.py``). Each frame's time is the node's published simulation time,
which never goes back: simulation time plus ``clock.offset_s``, whose changes (a reset, or a
divergence sent back to rest) are on ``/parameter_events``, their value the published time the
new run starts from. It is the recorded ``sim_time`` of the frame's stamp
(``bags/files/sim_time.py``), or, in a recording without it, the stamp itself where the node
stamped with simulation time. So each change is applied at the simulation time it took effect
at, and each reset where the new run starts: the re-run reproduces the recorded frames to
float32 round-off however late the graph delivered the events. A recording without
``applied_parameter_events`` (made before the node published it, or without the topic) has its
changes applied before the first frame received after them, as close as the delivery allows.
The re-run's frames are stamped with simulation time.
"""
from __future__ import annotations

from pathlib import Path

from modal_spring_ros.bags.files.applied_changes import applied_changes, event_values
from modal_spring_ros.bags.files.capture import POINTS_TOPIC, RunBagWriter
from modal_spring_ros.bags.files.reader import BagReader
from modal_spring_ros.bags.files.sim_time import sim_time_topic, simulation_times
from modal_spring_ros.bags.files.writer import BagError
from modal_spring_ros.bags.messages.stamps import to_nanoseconds, to_seconds
from modal_spring_ros.core.auto.watch.run_watch import watch_of
from modal_spring_ros.core.bases.derivatives import DEFAULT_DIRECTIONS
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation, rebuild
from modal_spring_ros.core.simulations import DivergenceError
from modal_spring_ros.ros.inputs.input_kinds import InputKind, INPUTS, WrenchAt
from modal_spring_ros.ros.parameters import (CLOCK_OFFSET, config_from_parameters, PARAMETERS,
                                             REBUILD_PARAMETERS)
from modal_spring_ros.ros.stream.stream_time import stamps_in_simulation_time
from modal_spring_ros.ros.tools.installed_messages import installed_message
from modal_spring_ros.runs.sample_cache import sample_cache
from modal_spring_ros.scenes.fields.limits import available_memory
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import PointCloud2


def parameter_changes(bag: BagReader, node: str) -> list[tuple[int, int, dict]]:
    """
    (log time ns, stamp ns, {name: value}) of the parameter events of ``node`` in the bag.

    In the node's own capture the stamp is the simulation time the change took effect at.
    """
    if '/parameter_events' not in bag.topics:
        return []
    out = []
    for m in bag.messages(['/parameter_events']):
        event = installed_message(bag, m)
        if event.node != node:
            continue
        values = event_values(event)
        if values:
            out.append((m.log_time_ns, to_nanoseconds(event.stamp), values))
    return out


def recorded_inputs(bag: BagReader, kinds: tuple[InputKind, ...] = INPUTS
                    ) -> list[tuple[int, int, tuple[InputKind, object]]]:
    """
    Return the inputs a node's capture kept, as (log time ns, stamp ns, (kind, message)).

    Each kind's ``recorded_topic`` (poses the clamp followed, clicked points, ...), each message
    stamped with the simulation time it took effect at. A point kept on a kind's
    ``recorded_point_topic`` goes with the input recorded right after it (a wrench carried
    through TF, :class:`~modal_spring_ros.ros.inputs.input_kinds.WrenchAt`).
    """
    by_topic = {kind.recorded_topic: kind for kind in kinds if kind.recorded_topic in bag.topics}
    points = {kind.recorded_point_topic for kind in kinds} & set(bag.topics)
    if not by_topic:
        return []
    out, point = [], None
    for m in bag.messages(list(by_topic) + sorted(points)):
        message = installed_message(bag, m)
        if m.topic in points:
            point = message
            continue
        stamp = message.header.stamp
        if point is not None and by_topic[m.topic].recorded_point_topic is not None:
            message = WrenchAt(message, point)
        point = None
        out.append((m.log_time_ns, to_nanoseconds(stamp), (by_topic[m.topic], message)))
    return out


def frame_times(bag: BagReader, topic: str,
                stamped_in_sim_time: bool = True) -> list[tuple[int, float]]:
    """
    Return (log time ns, published simulation time s) of every frame placed, in log order.

    A frame is placed by the recorded ``sim_time`` of its stamp; in a recording without
    ``sim_time``, by its stamp when ``stamped_in_sim_time``.

    :raises BagError: no frame can be placed in simulation time.
    """
    times = simulation_times(bag, topic)
    if not times and not stamped_in_sim_time:
        raise BagError(f"{bag.path}: the frames on {topic} are stamped with the node's clock "
                       f'and the bag has no {sim_time_topic(topic)} to place them in simulation '
                       'time: record that topic too (modal_spring_record does by default), or '
                       'run the node with stamp:=sim')
    out = []
    for m in bag.messages([topic]):
        stamp = deserialize_message(m.data, PointCloud2).header.stamp
        if to_nanoseconds(stamp) in times:
            out.append((m.log_time_ns, times[to_nanoseconds(stamp)]))
        elif not times:
            out.append((m.log_time_ns, to_seconds(stamp)))
    if not out:
        raise BagError(f'{bag.path}: no frame on {topic} has its simulation time on '
                       f'{sim_time_topic(topic)}')
    return out


def resimulate(bag_path: str | Path, output: str | Path, topic: str = POINTS_TOPIC) -> int:
    """
    Re-run ``bag_path``'s simulation into the new bag ``output``; returns the frame count.

    :raises BagError: the bag does not describe a run, or the output cannot be written.
    """
    bag = BagReader(bag_path)
    rec = bag.run_record()
    scene = bag.scene()
    if scene is None or not ('config' in rec or 'parameters' in rec):
        raise BagError(f'{bag_path}: no run description (scene and settings); it was not '
                       'recorded by modal_spring_ros')
    if topic not in bag.topics:
        raise BagError(f'{bag_path}: no topic {topic}')
    changes: list[tuple[int, int, dict]] = []
    if 'config' in rec:
        config = SimulationConfig.from_dict(rec['config'])
        values = None
    else:
        values = dict(rec['parameters'])
        # recorded before the basis was a parameter: the rest modes were the only basis
        values.setdefault('modal.basis', 'rest')
        values.setdefault('modal.derivative_directions', DEFAULT_DIRECTIONS)
        # recorded before stamps had a choice: simulation time
        values.setdefault('stamp', 'sim')
        for name, (default, _) in PARAMETERS.items():   # parameters added since: defaults
            values.setdefault(name, default)
        config = config_from_parameters(values)
        changes = parameter_changes(bag, rec.get('node', '/modal_spring'))
    sim = build_simulation(scene, config, allow_unstable=True, samples=sample_cache(),
                           memory_available=available_memory())
    # a recorded configuration's watch falls back where the run did (a node's fallback is a
    # recorded parameter change)
    watch = (watch_of(sim, config.watch_s, run_s=float(rec.get('duration', 0.0)) or None)
             if values is None else None)
    frame_s = max(1, int(rec.get('frame_every', 0) or 1)) * sim.dt
    exact = rec.get('event_clock') == 'sim'   # the node's capture: frames and events in sim time
    frames = frame_times(bag, topic,
                         values is None or exact or stamps_in_simulation_time(values))
    writer = RunBagWriter(output, scene, config, dt=sim.dt,
                          frame_every=int(rec.get('frame_every', 0)),
                          duration=float(rec.get('duration', 0.0)),
                          frame_id=rec.get('frame_id', 'world'),
                          source='modal_spring_replay --resimulate')
    # a DDS recording's stamps: simulation time plus the node's offset (its capture's: none)
    offset = 0.0 if exact or values is None else float(values.get(CLOCK_OFFSET) or 0.0)
    applied = None if exact or values is None else applied_changes(
        bag, topic, rec.get('node', '/modal_spring'))
    # placed in simulation time: the changes the node said it applied, and each reset at the
    # published time its new run starts from (the offset's new value)
    timed = [] if applied is None else sorted(
        [(round(float(change[CLOCK_OFFSET]) * 1e9), True, change)
         for _, _, change in changes if CLOCK_OFFSET in change]
        + [(stamp, False, change) for stamp, change in applied],
        key=lambda event: (event[0], not event[1]))     # a reset before a change at its time
    # placed as received: every change of a recording without them, inputs and the capture's
    logged = sorted((changes if applied is None else [])
                    + (recorded_inputs(bag) if values is not None else []),
                    key=lambda event: event[0])

    def step_to(at: float) -> None:
        nonlocal sim, watch
        while sim.time < at - 0.5 * sim.dt:
            if watch is not None:
                sim, window = watch.before_step(sim, frame_s)
                watch = (watch if window is None or window.within
                         else watch.after_fallback(sim))
            try:
                sim.step()
            except DivergenceError:
                sim.reset()                    # as the node does

    try:
        for log_time, stamp in frames:
            half_ns = 0.5e9 * sim.dt
            # a change took effect before this frame when its time is a step or more before it
            # (a frame at that very time was published before the change); a reset at it
            while timed and (timed[0][0] <= stamp * 1e9 + half_ns if timed[0][1]
                             else timed[0][0] < stamp * 1e9 - half_ns):
                event_ns, reset, change = timed.pop(0)
                if reset:
                    sim.reset()
                    offset = float(change[CLOCK_OFFSET])
                else:
                    step_to(event_ns * 1e-9 - offset)
                sim, values = _apply(sim, values, change)
            while logged and logged[0][0] <= log_time and values is not None:
                _, event_stamp, change = logged.pop(0)
                if exact:   # step to the simulation time the node applied it at
                    step_to(event_stamp * 1e-9)
                if isinstance(change, tuple):      # an input: (kind, message)
                    kind, message = change
                    kind.apply(sim, message, values)
                    continue
                if CLOCK_OFFSET in change and not exact:   # the run went back to rest
                    sim.reset()
                    offset = float(change[CLOCK_OFFSET])
                sim, values = _apply(sim, values, change)
            at = stamp - offset
            if at < sim.time - 0.5 * sim.dt:      # the recording was reset (older bags)
                sim.reset()
            step_to(at)
            writer.frame(sim.time, sim.positions(), log_time_ns=log_time)
    finally:
        writer.close()
    return len(frames)


def _apply(sim, values: dict, change: dict):
    new = dict(values, **{k: v for k, v in change.items() if k in values})
    config = config_from_parameters(new)
    if any(new[k] != values[k] for k in REBUILD_PARAMETERS):
        fresh = rebuild(sim.model, sim.basis, config)
        fresh.take_over(sim)
        return fresh, new
    if config.band != sim.band:
        sim.set_band(config.band, config.transition_s)
    return sim, new

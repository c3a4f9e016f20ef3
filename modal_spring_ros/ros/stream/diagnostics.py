"""
The node's ``/diagnostics``.

A simulation status and a stream report in, a ``diagnostic_msgs/DiagnosticArray`` out.

:func:`diagnostic_array` is a pure function of plain values, so what the node reports in each
situation is tested without DDS, and reporting cannot fail on the state of a simulation that
has just failed: the node passes the last status it could read.
"""
from __future__ import annotations

import dataclasses

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from modal_spring_ros.core.simulations import SimulationStatus
from modal_spring_ros.ros.process.namesakes import namesakes_warning
from std_msgs.msg import Header

#: Achieved real-time factor below this share of the requested one is reported.
REALTIME_TOLERANCE = 0.9
#: A gap between frames longer than this many publish periods is reported as a stall.
STALL_PERIODS = 3.0


@dataclasses.dataclass(frozen=True)
class StreamReport:
    """What the simulation thread measured over one diagnostics window."""

    window_s: float = 0.0              # wall time the window covers
    window_valid: bool = True          # no reset, pause or rebuild inside the window
    achieved_rtf: float = 0.0
    requested_rtf: float = 1.0
    publish_period_s: float = 1.0 / 60.0
    step_us: float = 0.0               # mean wall time of one step
    frames: int = 0                    # frames published since the start
    frames_in_window: int = 0
    longest_gap_s: float = 0.0         # longest time between two frames in the window
    computing_modes: bool = False      # a parameter request is computing modes (now or then)
    paused: bool = False
    clock_stopped: bool = False        # the run keeps pace with a /clock that stood still
    strain_warning: float = 0.1
    divergences: int = 0
    last_divergence: str = ''
    diverged_recently: bool = False
    error: str = ''                    # a failure reported now (ERROR)
    anchor: str = ''                   # what the clamp follows (anchor.source topic)
    anchor_stale: bool = False         # no pose for a while: the clamp holds the last
    recording: str = ''                # why the capture (record.bag) stopped, if it did
    parameters_preparing: str = ''     # parameter changes accepted and still being prepared
    parameters_reverted: str = ''      # a change that failed after it was accepted, recently
    namesakes: int = 0                 # other nodes on the graph with this node's full name
    name: str = ''                     # this node's fully qualified name (for the namesakes)
    watched: str = 'off'               # what the watch of an automatic plan measured
    watch_beyond: str = ''             # a watched window beyond the tolerance, recently
    progress: str = ''                 # the last progress line of a change being prepared


@dataclasses.dataclass
class StreamWindow:
    """Bookkeeping of one diagnostics window (written by the simulation thread only)."""

    wall: float = 0.0
    sim_time: float = 0.0
    valid: bool = True
    pace: tuple[str, float] = ('wall', 0.0)  # the pace clock's reading at the start
    step_seconds: float = 0.0
    steps: int = 0
    frames: int = 0
    longest_gap: float = 0.0
    computing_modes: bool = False


def level_and_message(status: SimulationStatus, stream: StreamReport) -> tuple[int, str]:
    """
    Return the status level and its one-line message.

    The level is the most severe condition's; the message says every warning that holds, joined
    with '; ' as diagnostic_updater merges summaries (a host that stalls and cannot keep real
    time says both). An error says only itself.
    """
    warnings = []
    still = stream.paused or stream.clock_stopped      # no frames are owed
    if (not still and stream.window_valid and stream.requested_rtf > 0
            and stream.achieved_rtf < REALTIME_TOLERANCE * stream.requested_rtf):
        warnings.append(f'cannot keep real time: achieved real-time factor '
                        f'{stream.achieved_rtf:.2f} of {stream.requested_rtf:g}')
    if not still:
        if stream.window_valid and stream.frames_in_window == 0 and stream.window_s > 0:
            warnings.append(f'no frame published in the last {stream.window_s:.1f} s')
        elif stream.longest_gap_s > STALL_PERIODS * stream.publish_period_s:
            warnings.append(f'stream stalled for {stream.longest_gap_s:.2f} s'
                            + (' while computing modes for a band change'
                               if stream.computing_modes else ''))
    if status.forces.fell_back:
        warnings.append(f'spring forces fell back: {status.forces.description}')
    if stream.watch_beyond:
        warnings.append(stream.watch_beyond)
    if stream.anchor_stale:
        warnings.append(f'anchor pose: {stream.anchor}')
    if stream.recording:
        warnings.append(stream.recording)
    if stream.parameters_reverted:
        warnings.append(f'parameter change {stream.parameters_reverted}')
    if stream.namesakes:
        warnings.append(namesakes_warning(stream.namesakes, stream.name))
    if status.max_strain > stream.strain_warning and status.basis.startswith('rest'):
        # the rest modes' regime; the derivative basis follows the sway's rotation beyond it
        warnings.append(f'large deformation: spring strain {status.max_strain:.1%} beyond the '
                        f'small-deformation regime of the modal basis')
    if stream.error or stream.diverged_recently:
        return DiagnosticStatus.ERROR, (
            stream.error or f'{stream.last_divergence}; recovered: back to the rest state')
    if warnings:
        return DiagnosticStatus.WARN, '; '.join(reversed(warnings))
    if stream.clock_stopped and not stream.paused:
        return DiagnosticStatus.OK, 'waiting for /clock (use_sim_time): it has not advanced'
    return DiagnosticStatus.OK, 'paused' if stream.paused else 'streaming'


def status_values(status: SimulationStatus, stream: StreamReport) -> dict[str, str]:
    """Every figure the node reports, as key -> text."""
    return {
        'method': status.method,
        'band': status.band,
        'basis': status.basis,
        'basis precompute (s)': f'{status.basis_seconds:.3g}',
        'modes stepped': str(status.modes),
        'coordinates stepped': str(status.coordinates),
        'modes computed': str(status.modes_computed),
        'automatic mode choice': status.mode_choice,
        'automatic choice measured': status.measured,
        'automatic choice watched': stream.watched,
        'integrator': status.integrator,
        'dt (s)': f'{status.dt:g}',
        'spring forces': status.forces.description,
        'force model': status.forces.model,
        'force refresh (steps)': str(status.force_refresh),
        'measured force error': ('exact every step' if status.forces.error is None
                                 else f'{status.forces.error:.2e}'),
        'stability limit (s)': f'{status.stability_limit:.4g}',
        'step time (us)': f'{stream.step_us:.1f}',
        'requested real-time factor': f'{stream.requested_rtf:g}',
        'achieved real-time factor': f'{stream.achieved_rtf:.3f}',
        'simulation time (s)': f'{status.time:.3f}',
        'frames published': str(stream.frames),
        'largest spring strain': f'{status.max_strain:.5f}',
        'contacts': status.contacts,
        'divergence': stream.last_divergence or 'none',
        'divergences': str(stream.divergences),
        'paused': str(stream.paused).lower(),
        'longest gap between frames (s)': f'{stream.longest_gap_s:.3f}',
        'computing modes': str(stream.computing_modes).lower(),
        'parameter changes pending': stream.parameters_preparing or 'none',
        'nodes with this name': str(stream.namesakes + 1),
        **({'anchor pose': stream.anchor} if stream.anchor else {}),
        **({'progress': stream.progress} if stream.progress else {}),
    }


def diagnostic_array(status: SimulationStatus, stream: StreamReport, *, node: str,
                     hardware_id: str, stamp: Time) -> DiagnosticArray:
    """
    Return one ``DiagnosticArray`` with the simulation's status.

    Named ``<node name>: simulation`` as diagnostic_updater names a node's task (the name without
    its namespace); the ``node`` value holds the fully qualified name ``node``, which tells nodes
    in different namespaces apart.
    """
    level, message = level_and_message(status, stream)
    return _array(level, message, {'node': node, **status_values(status, stream)},
                  node=node, hardware_id=hardware_id, stamp=stamp)


def starting_array(progress: str, elapsed_s: float, *, node: str, hardware_id: str,
                   stamp: Time) -> DiagnosticArray:
    """
    Return the ``DiagnosticArray`` of a node still preparing its first frame.

    The status :func:`diagnostic_array` names, OK, with the last ``progress`` line as its
    message (``starting: computing the 8 lowest modes ...``) and how long the start has taken.
    """
    values = {'node': node, 'progress': progress, 'starting for (s)': f'{elapsed_s:.1f}'}
    return _array(DiagnosticStatus.OK, f'starting: {progress}', values, node=node,
                  hardware_id=hardware_id, stamp=stamp)


def _array(level: bytes, message: str, values: dict[str, str], *, node: str, hardware_id: str,
           stamp: Time) -> DiagnosticArray:
    name = f"{node.rsplit('/', 1)[-1]}: simulation"
    entry = DiagnosticStatus(level=level, name=name, message=message, hardware_id=hardware_id,
                             values=[KeyValue(key=k, value=v) for k, v in values.items()])
    return DiagnosticArray(header=Header(stamp=stamp), status=[entry])

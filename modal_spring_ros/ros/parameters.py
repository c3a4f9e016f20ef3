"""
The node's parameters.

Their table (defaults, descriptors, ranges), and how they map onto a
:class:`~modal_spring_ros.core.config.SimulationConfig`.

The rules a run's settings must meet live in the configuration; this module only names them as
the node does (``sim.dt``, ``filter.high_hz``, ...) and adds the rules of the stream itself
(publish rate, real-time factor, frame, stamp).
"""
from __future__ import annotations

import math
from typing import Any

from modal_spring_ros.core.bases.derivatives import DEFAULT_DIRECTIONS
from modal_spring_ros.core.bases.mode_selection import DEFAULT_TOLERANCE
from modal_spring_ros.core.config import (DEFAULT_STRAIN_WARNING, DEFAULT_TRANSITION_S,
                                          DEFAULT_WATCH_S,
                                          MAX_DIRECTIONS, MAX_FOLLOW_HZ, MAX_HORIZON_S,
                                          MIN_DIRECTIONS, SimulationConfig)
from modal_spring_ros.core.filter_band import BandError, FILTER_TYPES, FilterBand, UNITS
from modal_spring_ros.core.filter_response import (ACTS_ON, MAX_DAMPING_RATIO, MAX_ORDER,
                                                   MAX_TERM_DB, split_terms)
from modal_spring_ros.core.forces import FORCES
from modal_spring_ros.core.integrators import INTEGRATORS
from modal_spring_ros.core.motion.clamp_follower import DEFAULT_FOLLOW_HZ
from modal_spring_ros.core.simulations import DEFAULT_MAX_MODES, DEFAULT_STRAIN_LIMIT, METHODS
from modal_spring_ros.core.simulations.coordinates import BASES
from modal_spring_ros.scenes.resources import DEFAULT_SCENE
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, ParameterType

#: the one parameter the node sets itself (refused from anyone else)
FREQUENCIES = 'modal.frequencies_hz'
#: the published time at which the run's simulation time is 0 (reported by the node)
CLOCK_OFFSET = 'clock.offset_s'
#: header stamps of the points and mesh (auto: sim with publish_clock, else wall)
STAMPS = ('auto', 'sim', 'wall')
#: smallest non-zero real-time factor: below it the stream would stand still
MIN_REALTIME_FACTOR = 1e-3
#: the object's and the clamp's TF frames (under the node's namespace unless named)
OBJECT_FRAME, CLAMP_FRAME = 'modal_spring_object', 'modal_spring_clamp'


def _descriptor(description: str, type_: int, *, read_only: bool = False,
                float_range: tuple[float, float] | None = None,
                int_range: tuple[int, int] | None = None,
                constraints: str = '') -> ParameterDescriptor:
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

#: name -> (default, descriptor). Band edges carry no descriptor range: the configuration
#: checks them (finite, non-negative, low < high) and says so by name.
PARAMETERS: dict[str, tuple[Any, ParameterDescriptor]] = {
    'scene': (DEFAULT_SCENE, _descriptor(
        'Built-in scene name or path of a scene YAML file', _S, read_only=True)),
    'method': ('modal', _descriptor(
        'modal: step only the modes the filter keeps; full: every DOF in physical coordinates',
        _S, constraints='one of ' + ', '.join(METHODS))),
    'filter.type': ('allpass', _descriptor(
        'Which modes take part', _S, constraints='one of ' + ', '.join(FILTER_TYPES))),
    'filter.by': ('hz', _descriptor(
        'Band edges in Hz (filter.low_hz/high_hz) or as zero-based mode numbers '
        '(filter.low_mode/high_mode)', _S, constraints='hz or index')),
    'filter.low_hz': (0.0, _descriptor(
        'Lower band edge, Hz (highpass, bandpass, bandstop)', _D,
        constraints='finite, >= 0, below filter.high_hz')),
    'filter.high_hz': (1000.0, _descriptor(
        'Upper band edge, Hz (lowpass, bandpass, bandstop)', _D,
        constraints='finite, >= 0, above filter.low_hz')),
    'filter.low_mode': (0, _descriptor(
        'Lower band edge as a mode number (filter.by = index)', _I, int_range=(0, 1_000_000))),
    'filter.high_mode': (14, _descriptor(
        'Upper band edge as a mode number (filter.by = index)', _I, int_range=(0, 1_000_000))),
    'filter.transition_s': (DEFAULT_TRANSITION_S, _descriptor(
        'Fade time of modes leaving or entering the band (and of a change of gains), s', _D,
        float_range=(0.0, 60.0))),
    'filter.order': (0, _descriptor(
        'Butterworth order of the band edges (-3 dB at each edge); 0 = ideal edges (keep or '
        'drop). Needs filter.by hz', _I, int_range=(0, MAX_ORDER))),
    'filter.gains': ('', _descriptor(
        'Gain terms in dB, separated by spaces or commas: LOW:HIGH:DB (a range), '
        'peak:CENTER:WIDTH:DB, low_shelf:CORNER:DB, high_shelf:CORNER:DB (Hz); empty = none',
        _S, constraints=f'each within +-{MAX_TERM_DB:g} dB')),
    'filter.gains_act_on': ('output', _descriptor(
        'output: the gains scale what each mode adds to the streamed points (the motion stays '
        'physical); load: they scale the loads that drive each mode (the motion changes)', _S,
        constraints='one of ' + ', '.join(ACTS_ON))),
    'filter.damping': ('', _descriptor(
        'Damping ranges LOW:HIGH:RATIO, separated by spaces or commas: modes within LOW..HIGH '
        "Hz are damped with modal ratio RATIO instead of the scene's; empty = none", _S,
        constraints=f'RATIO from 0 to {MAX_DAMPING_RATIO:g}')),
    'integrator': ('explicit', _descriptor(
        "Newmark member: explicit (beta 0, the paper's) or average (beta 1/4, implicit)", _S,
        constraints='one of ' + ', '.join(INTEGRATORS))),
    'sim.dt': (0.0, _descriptor(
        "Simulation step, s; 0 = the scene's, else half the explicit stability limit", _D,
        float_range=(0.0, 1.0), constraints='0, or at least 1e-8')),
    'sim.strain_limit': (DEFAULT_STRAIN_LIMIT, _descriptor(
        'Spring strain treated as divergence', _D, read_only=True, float_range=(0.001, 100.0))),
    'sim.strain_warning': (DEFAULT_STRAIN_WARNING, _descriptor(
        'Spring strain above which the small-deformation basis is reported as strained (WARN)',
        _D, float_range=(0.0, 100.0))),
    'publish_rate_hz': (60.0, _descriptor(
        'Rate of points (and clock) messages, Hz', _D, float_range=(0.1, 1000.0))),
    'mesh_rate_hz': (10.0, _descriptor(
        'Rate of mesh markers, Hz (only while someone subscribes)', _D,
        float_range=(0.0, 1000.0))),
    'realtime_factor': (1.0, _descriptor(
        'Simulated seconds per wall second; 0 = as fast as possible (as many steps as fit '
        'between two frames)', _D, float_range=(0.0, 1000.0),
        constraints=f'0, or at least {MIN_REALTIME_FACTOR:g}')),
    'frame_id': ('world', _descriptor('header.frame_id of points and mesh', _S)),
    'stamp': ('auto', _descriptor(
        'header.stamp of points, mesh and TF: auto (sim with publish_clock, else wall: as ROS '
        'nodes stamp), sim (simulation time, as on /clock; never back: see clock.offset_s) or '
        "wall (the node's ROS clock when publishing: system time, or /clock's under "
        'use_sim_time); sim_time gives the simulation time of every frame', _S,
        constraints='auto, sim or wall')),
    'publish_clock': (False, _descriptor('Publish simulation time on /clock', _B)),
    'anchor.source': ('scene', _descriptor(
        "scene: the clamp moves as the scene's anchor_motion says; topic: it follows "
        'geometry_msgs/PoseStamped on anchor_pose; tf: it follows the TF frame anchor.frame '
        '(both relative to the first pose received)', _S,
        read_only=True, constraints='scene, topic or tf')),
    'anchor.frame': ('', _descriptor(
        'The TF frame the clamp follows with anchor.source tf (a gripper link), looked up in '
        'frame_id', _S, read_only=True)),
    'tf.publish': (True, _descriptor(
        "Broadcast the object's and the clamp's frames on /tf, under frame_id, with every "
        'frame of the stream', _B, read_only=True)),
    'tf.object_frame': ('', _descriptor(
        'TF frame the object rides (its rest shape moved as the clamp moves it); empty: '
        f"{OBJECT_FRAME} under the node's namespace (left/{OBJECT_FRAME} for a node in "
        '/left)', _S, read_only=True)),
    'tf.clamp_frame': ('', _descriptor(
        'TF frame at the clamp (the centre of the fixed particles, turned with the clamp); '
        f'not broadcast for a scene without fixed particles; empty: {CLAMP_FRAME} under the '
        "node's namespace", _S, read_only=True)),
    'anchor.follow_hz': (DEFAULT_FOLLOW_HZ, _descriptor(
        'Bandwidth of the critically damped filter the clamp follows poses through, Hz', _D,
        read_only=True, float_range=(0.1, MAX_FOLLOW_HZ))),
    'anchor.max_jump_m': (0.5, _descriptor(
        'A pose further than this from the last one accepted is refused, m', _D,
        float_range=(0.0, 1000.0))),
    'anchor.max_turn_deg': (30.0, _descriptor(
        'A pose turned more than this from the last one accepted is refused, degrees', _D,
        float_range=(0.0, 180.0))),
    'interaction.stiffness': (50.0, _descriptor(
        'Stiffness of the spring a /clicked_point pulls the nearest particle with, N/m', _D,
        float_range=(0.0, 1e6))),
    'interaction.hold_s': (2.0, _descriptor(
        'How long a /clicked_point pulls and a wrench pushes, s of simulation time', _D,
        float_range=(0.0, 3600.0))),
    'interaction.max_force_n': (5.0, _descriptor(
        'Largest force a /clicked_point pulls with and a wrench pushes with, N (the largest '
        'torque of a wrench: this times interaction.radius, N m)', _D, float_range=(0.0, 1e6))),
    'interaction.radius': (0.0, _descriptor(
        'A wrench acts on the free particles within this distance of the origin of its frame '
        '(the nearest one when none is), and a /clicked_point this close to a particle is on '
        'the object (it grabs), m; 0: one and a half spring lengths (the median rest length)',
        _D, float_range=(0.0, 1000.0))),
    'grasp.frames': ('', _descriptor(
        'TF frames of grippers, separated by spaces or commas: each is looked up in TF and '
        'closes (holds the free particles within grasp.reach of it) or opens on a '
        'sensor_msgs/JointState on grasp naming it (position 1 closes, 0 opens); empty: no '
        'grippers', _S, read_only=True)),
    'grasp.reach': (0.0, _descriptor(
        'A gripper closing holds the free particles within this distance of its frame, m; 0: '
        'interaction.radius (or its default)', _D, float_range=(0.0, 1000.0))),
    'modal.auto': (False, _descriptor(
        "Keep the fewest modes (within the band) that meet modal.tolerance for the scene's "
        'loads (gravity, anchor motion), the step they allow unless sim.dt is set, and the '
        'basis (rest or derivatives, by predicted error and cost, in place of modal.basis)',
        _B)),
    'modal.tolerance': (DEFAULT_TOLERANCE, _descriptor(
        'Relative error the automatic choice must meet over modal.horizon, measured by its '
        'pilot run', _D, float_range=(1e-6, 0.5))),
    'modal.horizon': (0.0, _descriptor(
        'Run length, s, that modal.tolerance holds over (an undamped scene drifts further the '
        "longer it runs); 0 = the scene's simulation.duration", _D,
        float_range=(0.0, MAX_HORIZON_S))),
    'modal.watch': (DEFAULT_WATCH_S, _descriptor(
        "With modal.auto: the plan's error is measured again from the run's own state every "
        'this many simulated seconds (less often where watching would take more than a '
        'quarter of a core at real time), reported on /diagnostics, and beyond '
        'modal.tolerance the node falls back by setting its parameters (method full, or the '
        'whole band on a richer basis); 0 = not watched', _D,
        float_range=(0.0, MAX_HORIZON_S))),
    'modal.forces': ('exact', _descriptor(
        'Spring forces: exact (every spring every step, the paper), refreshed (every spring '
        'every modal.force_refresh steps, a tangent between) or sampled (a weighted sample of '
        'the springs within modal.tolerance, trained once per band and cached); modal.auto '
        'chooses in its place', _S, constraints='one of ' + ', '.join(FORCES))),
    'modal.force_refresh': (0, _descriptor(
        'Steps between exact evaluations of the nonlinear spring forces (1 = every step, as '
        'the paper; N > 1 continues them along the static tangent in between); 0 = every '
        'step, or what modal.auto chooses', _I, int_range=(0, 10_000))),
    'modal.basis': ('derivatives', _descriptor(
        "Coordinates of the modal method: rest (the paper's rest modes of the band) or "
        "derivatives (the band's rest modes plus their modal derivatives and static load "
        'vectors: right beyond small deformation)', _S, constraints='rest or derivatives')),
    'modal.derivative_directions': (DEFAULT_DIRECTIONS, _descriptor(
        'Modal-derivative directions a band adds (modal.basis = derivatives)', _I,
        int_range=(MIN_DIRECTIONS, MAX_DIRECTIONS))),
    'record.bag': ('', _descriptor(
        'If set, a new bag folder that every published frame is written to directly (no DDS), '
        'with the scene, the parameters and every change: re-simulates exactly', _S,
        read_only=True)),
    'modal.max_modes': (DEFAULT_MAX_MODES, _descriptor(
        'Most modes computed on scenes too large for a dense eigensolver', _I, read_only=True,
        int_range=(1, 100_000))),
    'stream_early': (True, _descriptor(
        'Stream before the slow part is ready: on large scenes the lowest modes and refreshed '
        'springs while the rest of the band and the spring sample are prepared; with '
        'modal.auto the full run (or the band on its rest modes) while the plan is measured; '
        'false: the first frame waits for them',
        _B, read_only=True)),
}

#: The frequencies of the computed modes. Set by the node alone (more modes are computed when
#: a band needs them); a request from outside is refused in the node's on-set callback.
FREQUENCIES_DESCRIPTOR = _descriptor(
    'Frequencies of the computed modes, Hz (ascending); read-only: the node updates it when '
    'a band needs more modes', ParameterType.PARAMETER_DOUBLE_ARRAY)
CLOCK_OFFSET_DESCRIPTOR = _descriptor(
    "Published time (sim stamps, /clock) at which the run's simulation time is 0, s; "
    'read-only: a reset or a divergence moves it on, so that published time never goes back',
    ParameterType.PARAMETER_DOUBLE)

#: parameters whose change rebuilds the simulation (state and time carried over); the other
#: ``filter.*`` parameters change the band of the running one
REBUILD_PARAMETERS = frozenset({'method', 'integrator', 'sim.dt', 'modal.auto',
                                'modal.tolerance', 'modal.horizon', 'modal.force_refresh',
                                'modal.basis', 'modal.max_modes',
                                'modal.forces',
                                'modal.derivative_directions'})
#: parameters of the band
BAND_PARAMETERS = frozenset({'filter.type', 'filter.by', 'filter.low_hz', 'filter.high_hz',
                             'filter.low_mode', 'filter.high_mode', 'filter.transition_s',
                             'filter.order', 'filter.gains', 'filter.gains_act_on',
                             'filter.damping'})
#: parameters whose change has a slow part (prepared off the parameter services' thread)
SLOW_PARAMETERS = REBUILD_PARAMETERS | BAND_PARAMETERS
#: string parameters with a fixed set of values
CHOICES = {'method': tuple(METHODS), 'filter.type': FILTER_TYPES, 'filter.by': UNITS,
           'filter.gains_act_on': ACTS_ON,
           'integrator': tuple(INTEGRATORS), 'stamp': STAMPS, 'modal.basis': BASES,
           'modal.forces': FORCES}
#: configuration field -> parameter name, so that configuration errors name the parameter
CONFIG_NAMES = {'method': 'method', 'auto': 'modal.auto', 'integrator': 'integrator',
                'dt': 'sim.dt', 'transition_s': 'filter.transition_s',
                'max_modes': 'modal.max_modes', 'strain_limit': 'sim.strain_limit',
                'tolerance': 'modal.tolerance', 'force_refresh': 'modal.force_refresh',
                'basis': 'modal.basis', 'derivative_directions': 'modal.derivative_directions',
                'anchor': 'anchor.source', 'follow_hz': 'anchor.follow_hz',
                'forces': 'modal.forces', 'horizon_s': 'modal.horizon',
                'watch_s': 'modal.watch',
                'type': 'filter.type', 'by': 'filter.by', 'low_hz': 'filter.low_hz',
                'high_hz': 'filter.high_hz', 'low_mode': 'filter.low_mode',
                'high_mode': 'filter.high_mode', 'order': 'filter.order',
                'gains': 'filter.gains', 'acts_on': 'filter.gains_act_on',
                'damping': 'filter.damping'}


def band_from_parameters(values: dict[str, Any]) -> FilterBand:
    """Return the band (and its shape) described by the ``filter.*`` parameters."""
    by = values['filter.by']
    edges = ('filter.low_mode', 'filter.high_mode') if by == 'index' else ('filter.low_hz',
                                                                           'filter.high_hz')
    return FilterBand(values['filter.type'], float(values[edges[0]]), float(values[edges[1]]),
                      by, order=int(values.get('filter.order', 0)),
                      gains=split_terms(values.get('filter.gains', '')),
                      acts_on=values.get('filter.gains_act_on', 'output'),
                      damping=split_terms(values.get('filter.damping', '')))


def config_from_parameters(values: dict[str, Any]) -> SimulationConfig:
    """
    Return the run the parameters describe, validated (errors name the parameter).

        ConfigError, BandError: a value out of range.
    """
    check_stream(values)
    return SimulationConfig(
        method=values['method'], band=band_from_parameters(values),
        integrator=values['integrator'], dt=values['sim.dt'] or None,
        transition_s=values['filter.transition_s'], max_modes=values['modal.max_modes'],
        strain_limit=values['sim.strain_limit'], auto=values.get('modal.auto', False),
        tolerance=values.get('modal.tolerance', DEFAULT_TOLERANCE),
        force_refresh=values.get('modal.force_refresh', 0),
        basis=values.get('modal.basis', 'rest'),
        derivative_directions=values.get('modal.derivative_directions', DEFAULT_DIRECTIONS),
        forces=values.get('modal.forces', 'exact'),
        horizon_s=values.get('modal.horizon', 0.0) or None,
        planning_share=None,    # a stream has no length: planning is paid once, saved after
        watch_s=values.get('modal.watch', DEFAULT_WATCH_S),
        anchor=values.get('anchor.source', 'scene'),
        follow_hz=values.get('anchor.follow_hz', DEFAULT_FOLLOW_HZ),
    ).validate(CONFIG_NAMES)


def broadcast_frames(values: dict[str, Any], namespace: str = '/') -> tuple[str, str]:
    """
    Return the object's and the clamp's TF frame names a node in ``namespace`` broadcasts.

    An empty name is the default one under the namespace (``left/modal_spring_object`` in
    ``/left``, ``modal_spring_object`` in ``/``): two namespaced nodes of one graph broadcast
    frames of their own. A name given is used as given (without a leading slash, as tf2 has it).
    """
    prefix = namespace.strip('/')

    def name(given: str, default: str) -> str:
        given = given.lstrip('/')
        return given or (f'{prefix}/{default}' if prefix else default)
    return (name(values.get('tf.object_frame', ''), OBJECT_FRAME),
            name(values.get('tf.clamp_frame', ''), CLAMP_FRAME))


def check_frames(values: dict[str, Any]) -> None:
    """Check the TF frame names (anchor.frame with anchor.source tf, the broadcast frames)."""
    frame_id = values['frame_id'].lstrip('/')
    if values.get('anchor.source') == 'tf':
        followed = values.get('anchor.frame', '').lstrip('/')
        if not followed:
            raise ValueError('anchor.source tf needs anchor.frame: the TF frame the clamp '
                             'follows')
        if followed == frame_id:
            raise ValueError(f"anchor.frame '{followed}' is frame_id: the clamp would follow "
                             'the frame it is placed in')
    if values.get('tf.publish', False):
        names = broadcast_frames(values)
        for name, frame in zip(('tf.object_frame', 'tf.clamp_frame'), names):
            if frame == frame_id:
                raise ValueError(f"{name} '{frame}' is frame_id: a frame cannot be its own "
                                 'parent')
        if names[0] == names[1]:
            raise ValueError(f"tf.object_frame and tf.clamp_frame are both '{names[0]}'")


def check_stream(values: dict[str, Any]) -> None:
    """
    Return the rules of the stream itself and of the string choices.

    Raises ValueError naming the parameter.
    """
    for name, allowed in CHOICES.items():
        if values[name] not in allowed:
            raise ValueError(f"{name} '{values[name]}' must be one of {', '.join(allowed)}")
    for name in ('filter.low_hz', 'filter.high_hz'):
        v = float(values[name])
        if not math.isfinite(v):
            raise BandError(f'{name} ({v}) must be finite')
        if v < 0:
            raise BandError(f'{name} ({v:g}) must not be negative')
    if not values['frame_id']:
        raise ValueError('frame_id must not be empty')
    check_frames(values)
    rtf = values['realtime_factor']
    if 0.0 < rtf < MIN_REALTIME_FACTOR:
        raise ValueError(f'realtime_factor ({rtf:g}) must be 0 (as fast as possible) or at '
                         f'least {MIN_REALTIME_FACTOR:g}: slower, the stream stands still')

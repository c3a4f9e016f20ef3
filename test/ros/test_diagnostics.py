"""/diagnostics as a pure function of a simulation status and a stream report (no DDS)."""
from __future__ import annotations

import dataclasses

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticStatus
from modal_spring_ros.core.forces import ForceReport
from modal_spring_ros.core.simulations import SimulationStatus
from modal_spring_ros.ros.stream.diagnostics import diagnostic_array, starting_array, StreamReport
import pytest

OK, WARN, ERROR = DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR

STATUS = SimulationStatus(
    method='modal', band='lowpass <= 20 Hz', basis='rest: 4 modes', basis_seconds=0.012,
    modes=4, coordinates=4, modes_computed=180,
    mode_choice='off', integrator='explicit', dt=5e-4, force_refresh=1,
    stability_limit=0.0123, time=2.5, steps=5000, max_strain=0.01, fading=False)
STREAM = StreamReport(window_s=1.0, achieved_rtf=1.0, requested_rtf=1.0, step_us=31.4,
                      frames=600, frames_in_window=60, longest_gap_s=0.02, strain_warning=0.1)


def _entry(status=STATUS, stream=STREAM):
    array = diagnostic_array(status, stream, node='/robot/modal_spring',
                             hardware_id='sheet_10x10', stamp=Time(sec=3, nanosec=5))
    assert len(array.status) == 1 and array.header.stamp == Time(sec=3, nanosec=5)
    entry = array.status[0]
    return entry, {kv.key: kv.value for kv in entry.values}


def test_a_steady_stream_is_ok_with_every_figure():
    entry, values = _entry()
    assert (entry.level, entry.message) == (OK, 'streaming')
    # named as diagnostic_updater names a node's task; the namespace is in a value of its own
    assert entry.name == 'modal_spring: simulation' and entry.hardware_id == 'sheet_10x10'
    assert values['node'] == '/robot/modal_spring'
    assert values['band'] == 'lowpass <= 20 Hz' and values['modes stepped'] == '4'
    assert values['modes computed'] == '180' and values['dt (s)'] == '0.0005'
    assert values['measured force error'] == 'exact every step'
    assert values['force model'] == 'exact'
    assert values['stability limit (s)'] == '0.0123' and values['step time (us)'] == '31.4'
    assert values['simulation time (s)'] == '2.500' and values['frames published'] == '600'
    assert values['paused'] == 'false' and values['divergence'] == 'none'
    assert values['nodes with this name'] == '1'


def test_refreshed_forces_report_their_error():
    refreshed = ForceReport('refreshed', 'exact every 10 steps, tangent between', 10, 3.2e-4)
    _, values = _entry(dataclasses.replace(STATUS, force_refresh=10, forces=refreshed))
    assert values['force refresh (steps)'] == '10' and values['force model'] == 'refreshed'
    assert values['measured force error'] == '3.20e-04'


@pytest.mark.parametrize('changes, level, message', [
    ({'paused': True, 'frames_in_window': 0, 'achieved_rtf': 0.0}, OK, 'paused'),
    ({'achieved_rtf': 0.5}, WARN, 'cannot keep real time: achieved real-time factor 0.50 of 1'),
    ({'achieved_rtf': 0.5, 'window_valid': False}, OK, 'streaming'),  # a reset in the window
    ({'requested_rtf': 0.0, 'achieved_rtf': 12.0}, OK, 'streaming'),  # as fast as possible
    ({'longest_gap_s': 0.5}, WARN, 'stream stalled for 0.50 s'),
    ({'longest_gap_s': 0.5, 'computing_modes': True}, WARN,
     'stream stalled for 0.50 s while computing modes for a band change'),
    ({'frames_in_window': 0}, WARN, 'no frame published in the last 1.0 s'),
    ({'error': "simulation thread failed: IndexError('x')"}, ERROR,
     "simulation thread failed: IndexError('x')"),
    ({'diverged_recently': True, 'divergences': 1, 'last_divergence': 'diverged at t = 1 s'},
     ERROR,
     'diverged at t = 1 s; recovered: back to the rest state'),
    ({'namesakes': 1, 'name': '/robot/modal_spring'}, WARN,
     '1 other node named /robot/modal_spring on this domain: their topics, parameters and '
     'services mix with these (give each node its own name or namespace)'),
])
def test_each_condition_has_its_level_and_message(changes, level, message):
    entry, _ = _entry(stream=dataclasses.replace(STREAM, **changes))
    assert (entry.level, entry.message) == (level, message)


def test_every_warning_that_holds_is_said_as_diagnostic_updater_merges_them():
    """A loaded host stalls and cannot keep real time: one message says both."""
    entry, _ = _entry(stream=dataclasses.replace(STREAM, requested_rtf=200.0, achieved_rtf=3.0,
                                                 longest_gap_s=0.5))
    assert entry.level == WARN
    assert entry.message == ('stream stalled for 0.50 s; cannot keep real time: achieved '
                             'real-time factor 3.00 of 200')


def test_large_deformation_warns_and_an_error_outranks_it():
    strained = dataclasses.replace(STATUS, max_strain=0.25)
    derived = dataclasses.replace(strained, basis='derivatives: 4 modes + 15 + 2')
    assert _entry(status=derived)[0].level == OK        # the basis made for it: no warning
    entry, values = _entry(status=strained)
    assert entry.level == WARN and entry.message.startswith('large deformation: spring strain '
                                                            '25.0%')
    assert values['largest spring strain'] == '0.25000'
    entry, _ = _entry(strained, dataclasses.replace(STREAM, error='reset failed'))
    assert (entry.level, entry.message) == (ERROR, 'reset failed')


def test_sampled_springs_are_described_and_a_fallback_warns():
    sampled = dataclasses.replace(STATUS, forces=ForceReport(
        'sampled', 'sampled: 204 of 39402 springs, held-out error 0.37%, run-time 0.21%', 1,
        0.0021))
    entry, values = _entry(status=sampled)
    assert entry.level == OK and values['spring forces'].startswith('sampled: 204 of 39402')
    assert values['measured force error'] == '2.10e-03'
    fell = dataclasses.replace(STATUS, forces=ForceReport(
        'sampled', 'exact (the 3-spring sample fell back: error 4.10% beyond 1.00%)', 1, 0.041,
        fell_back=True))
    entry, _ = _entry(status=fell)
    assert entry.level == WARN
    assert entry.message == ('spring forces fell back: exact (the 3-spring sample fell back: '
                             'error 4.10% beyond 1.00%)')


def test_a_silent_pose_stream_warns_that_the_clamp_holds_the_last_pose():
    stale = dataclasses.replace(STREAM, anchor='no pose for 1.3 s: holding the last',
                                anchor_stale=True)
    entry, values = _entry(stream=stale)
    assert (entry.level, entry.message) == (WARN, 'anchor pose: no pose for 1.3 s: holding '
                                                  'the last')
    assert values['anchor pose'] == 'no pose for 1.3 s: holding the last'
    assert 'anchor pose' not in _entry()[1]               # the scene's own motion: not shown


def test_a_watched_plan_reports_its_windows_and_a_window_beyond_warns():
    watched = '3 windows: last 0.64% over 3.01 s from t = 30 s against the full run'
    entry, values = _entry(stream=dataclasses.replace(STREAM, watched=watched))
    assert (entry.level, values['automatic choice watched']) == (OK, watched)
    assert _entry()[1]['automatic choice watched'] == 'off'
    beyond = ('automatic plan beyond its tolerance 1.00%: 2.67% over 3.01 s from t = 21.7 s '
              'against the full run; falling back to the full run')
    entry, _ = _entry(stream=dataclasses.replace(STREAM, watched=beyond, watch_beyond=beyond))
    assert (entry.level, entry.message) == (WARN, beyond)


def test_a_node_still_starting_says_what_it_prepares_under_the_running_name():
    array = starting_array('computing the 8 lowest modes', 3.25, node='/robot/modal_spring',
                           hardware_id='sheet_316x316', stamp=Time(sec=1))
    (entry,) = array.status
    values = {kv.key: kv.value for kv in entry.values}
    assert (entry.level, entry.message) == (OK, 'starting: computing the 8 lowest modes')
    assert entry.name == _entry()[0].name and entry.hardware_id == 'sheet_316x316'
    assert values == {'node': '/robot/modal_spring', 'progress': 'computing the 8 lowest modes',
                      'starting for (s)': '3.2'}


def test_the_progress_of_a_change_being_prepared_is_reported_only_with_one():
    assert 'progress' not in _entry()[1]
    preparing = dataclasses.replace(STREAM, parameters_preparing='modal.max_modes=256',
                                    progress='computing the 32 lowest modes')
    values = _entry(stream=preparing)[1]
    assert values['progress'] == 'computing the 32 lowest modes'
    assert values['parameter changes pending'] == 'modal.max_modes=256'

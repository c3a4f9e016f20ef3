"""
The node's life cycle over real DDS: clean ends on signals, and a band-change stress test.

Each test starts its own node in its own namespace (so only its own stream is seen).
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from helpers import niceness, process_group, REPO, spawned_niceness
import numpy as np
import pytest
from rclpy.qos import DurabilityPolicy, ReliabilityPolicy
from ros_harness import (Client, frames_since, node_of, node_with_client, NodeProcess,
                         stderr_excerpt, streaming_statuses, wait_for)
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import PointCloud2

pytestmark = pytest.mark.ros

NODE = 'modal_spring'
RATE = 60.0
#: the steady stream watched before the band-change stress, s
STEADY_BEFORE_S = 5.0


def stamp_s(msg) -> float:
    """Return a message's header stamp in seconds."""
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


def test_sigint_and_sigterm_end_the_node_cleanly():
    for sig in (signal.SIGINT, signal.SIGTERM):
        node = NodeProcess(namespace='lifecycle')
        client = Client('sig_client')
        points = client.collect(PointCloud2, '/lifecycle/points')
        assert wait_for(lambda: len(points) > 3, 30)
        client.close()
        code, _, err = node.interrupt(sig=sig)
        assert code == 0, stderr_excerpt(err, 3000)
        assert 'Traceback' not in err
        assert 'failed' not in err and 'ERROR' not in err, stderr_excerpt(err, 3000)


SUBSCRIBER = """
import sys, rclpy
from sensor_msgs.msg import PointCloud2
rclpy.init()
node = rclpy.create_node('doomed_subscriber')
got = []
node.create_subscription(PointCloud2, sys.argv[1], got.append, 10)
while len(got) < 3:
    rclpy.spin_once(node, timeout_sec=0.1)
print('receiving', flush=True)
while True:
    rclpy.spin_once(node, timeout_sec=0.1)
"""


def test_sigint_right_after_a_subscriber_was_killed_ends_the_node_every_time():
    """A subscriber SIGKILLed (no goodbye on DDS), then Ctrl-C: the node ends, again and again."""
    for attempt in range(3):
        node = NodeProcess(namespace='orphaned')
        subscriber = subprocess.Popen([sys.executable, '-c', SUBSCRIBER, '/orphaned/points'],
                                      stdout=subprocess.PIPE, text=True)
        try:
            assert subscriber.stdout.readline().strip() == 'receiving', attempt
        finally:
            subscriber.kill()
            subscriber.wait(10)
        code, _, err = node.interrupt()
        assert code == 0 and 'Traceback' not in err, (attempt, stderr_excerpt(err))


@pytest.mark.slow
def test_stress_band_changes_every_50ms_keep_the_stream_whole():
    # stamped with the node's clock when it publishes: gaps are the node's, not the delays of
    # this (busy) test process receiving them
    node = NodeProcess('stamp:=wall', namespace='stress')
    client = Client('stress_client')
    points = client.collect(PointCloud2, '/stress/points', qos=500)
    diagnostics = client.collect(DiagnosticArray, '/diagnostics')
    try:
        assert wait_for(lambda: len(points) > 3, 30)
        bands = [('lowpass', 0.0, 12.0), ('highpass', 10.0, 11.0), ('bandpass', 5.0, 40.0),
                 ('bandstop', 8.0, 30.0), ('allpass', 0.0, 1.0)]
        # Each band once first: its first request computes what the band adds to its modes
        # (the derivatives basis), once per band; what is measured is switching between bands.
        for kind, low, high in bands:
            (result,) = client.set_parameters(f'stress/{NODE}', atomically=True, filter__type=kind,
                                              filter__low_hz=low, filter__high_hz=high)
            assert result.successful, result.reason
        time.sleep(1.0)
        before = time.monotonic()
        time.sleep(STEADY_BEFORE_S)
        start = time.monotonic()
        for k in range(120):  # about 10 s: each request answers in a few ms, then 50 ms pause
            kind, low, high = bands[k % len(bands)]
            (result,) = client.set_parameters(f'stress/{NODE}', atomically=True, filter__type=kind,
                                              filter__low_hz=low, filter__high_hz=high)
            assert result.successful, result.reason
            time.sleep(0.05)
        changing = time.monotonic() - start
        assert node.proc.poll() is None                       # still running
        window = [(t, m) for t, m in points if start <= t < start + changing]
        gaps = np.diff([stamp_s(m) for _, m in window])
        # the same run's steady stream before the changes and after them (as long as they
        # took): what this machine's load does to the stream without them (a busy host's
        # delays are not the node's, and its load changes while the test runs)
        quiet = time.monotonic()
        time.sleep(changing)
        steady = np.concatenate([
            np.diff([stamp_s(m) for t, m in points if before <= t < start]),
            np.diff([stamp_s(m) for t, m in points if t >= quiet])])
        # frames at the publish rate (or at the rate a busy host kept without the changes)
        assert np.median(gaps) < 1.5 * max(1.0 / RATE, float(np.median(steady)))
        # no stall the band changes caused: the changes' gaps stay within what the steady
        # window shows (its longest, and its 99th percentile for the many)
        assert gaps.max() < 4.0 * max(steady.max(), 1.0 / RATE), (gaps.max(), steady.max())
        assert np.percentile(gaps, 99) < 3.0 * max(np.percentile(steady, 99), 1.0 / RATE)
        for _, m in window:
            assert np.isfinite(np.frombuffer(bytes(m.data), dtype='<f4')).all()
        mine = [d.status[0] for t, d in diagnostics
                if t >= start and node_of(d.status[0]).startswith('/stress/')]
        assert mine
        assert DiagnosticStatus.ERROR not in [s.level for s in mine]
    finally:
        client.close()
        code, _, err = node.interrupt()
        assert code == 0 and 'Traceback' not in err


def test_params_file_is_accepted_as_ros2_run_would_pass_it(tmp_path):
    """The shipped file (the node's defaults) with one value edited, as a user would."""
    from diagnostic_msgs.msg import DiagnosticArray as Diag
    text = (REPO / 'config' / 'modal_spring.yaml').read_text()
    params = tmp_path / 'mine.yaml'
    params.write_text(text.replace('filter.type: "allpass"', 'filter.type: "lowpass"')
                      .replace('filter.high_hz: 1000.0', 'filter.high_hz: 45.0'))
    import subprocess

    from ros_harness import console_script
    proc = subprocess.Popen([console_script('modal_spring_node'), '--ros-args',
                             '--params-file', str(params), '-r', '__ns:=/params'],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=dict(os.environ))
    client = Client('params_client')
    diags = client.collect(Diag, '/diagnostics')
    try:
        assert wait_for(lambda: streaming_statuses(diags, '/params/'), 30)
        status = streaming_statuses(diags, '/params/')[0]
        values = {kv.key: kv.value for kv in status.values}
        assert values['band'] == 'lowpass <= 45 Hz' and values['method'] == 'modal'
    finally:
        client.close()
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=15)
    assert proc.returncode == 0


def _status(diags, prefix):
    return [(t, d.status[0]) for t, d in diags if node_of(d.status[0]).startswith(prefix)]


def test_mesh_and_clock_are_published_when_asked_for():
    from visualization_msgs.msg import Marker
    with node_with_client('publish_clock:=true', 'mesh_rate_hz:=5.0',
                          namespace='extras') as (node, client):
        points = client.collect(PointCloud2, '/extras/points')
        meshes = client.collect(Marker, '/extras/mesh')
        clocks = client.collect(Clock, '/clock')
        assert wait_for(lambda: len(meshes) >= 10 and len(clocks) > 10, 30)
        marker = meshes[-1][1]
        assert marker.type == Marker.TRIANGLE_LIST and marker.header.frame_id == 'world'
        assert len(marker.points) == 3 * 2 * 81 == len(marker.colors)   # 2 per cell
        assert all(0.0 <= c.r <= 1.0 and c.a == 1.0 for c in marker.colors)
        # about every 0.2 s of wall time (mesh_rate_hz 5), whatever the real-time factor a busy
        # machine allows: judged after the first markers (those bunch up when DDS delivers what
        # it queued while the subscriber was matching)
        received = [t for t, _ in meshes][4:]
        rate = (len(received) - 1) / (received[-1] - received[0])
        assert 2.5 <= rate <= 7.5, rate
        # /clock carries the simulation time of the frames
        stamps = {(m.header.stamp.sec, m.header.stamp.nanosec) for _, m in points}
        assert sum((c.clock.sec, c.clock.nanosec) in stamps for _, c in clocks) > 5


def test_divergence_is_reported_not_published_and_recovered_from():
    # A strain limit below the sheet's ordinary 0.7 %: every drop from rest "diverges".
    with node_with_client('sim.strain_limit:=0.004', namespace='diverge') as (node, client):
        points = client.collect(PointCloud2, '/diverge/points', qos=500)
        diags = client.collect(DiagnosticArray, '/diagnostics')
        assert wait_for(lambda: any(s.level == DiagnosticStatus.ERROR
                                    for _, s in _status(diags, '/diverge/')), 30)
        errors = [s for _, s in _status(diags, '/diverge/') if s.level == DiagnosticStatus.ERROR]
        assert 'exceeds the limit 0.004' in errors[0].message
        # recovered (or, if the first three came before this client saw the node, held)
        assert ('back to the rest state' in errors[0].message
                or 'holding at rest' in errors[0].message), errors[0].message
        window = frames_since(points, time.monotonic(), 2 * RATE)   # goes on (not frozen)
        for m in window:                                  # and never carries a bad frame
            cloud = np.frombuffer(bytes(m.data), dtype='<f4').reshape(-1, 4)
            assert np.isfinite(cloud).all()
        values = {kv.key: kv.value for kv in errors[-1].values}
        assert int(values['divergences']) >= 1
        # the same drop diverging again and again: held at rest after three in a row, said
        # once, and the count stops growing (no endless loop of recoveries)
        assert wait_for(lambda: any('holding at rest' in s.message
                                    for _, s in _status(diags, '/diverge/')), 10)
        held = [s for _, s in _status(diags, '/diverge/') if 'holding at rest' in s.message]
        assert held[0].message.startswith('3 divergences in a row')
        count = int({kv.key: kv.value for kv in held[0].values}['divergences'])
        time.sleep(2.0)
        last = _status(diags, '/diverge/')[-1][1]
        assert int({kv.key: kv.value for kv in last.values}['divergences']) == count


def test_a_host_that_cannot_keep_real_time_says_so():
    with node_with_client('method:=full', 'realtime_factor:=200.0',
                          namespace='slow') as (node, client):
        diags = client.collect(DiagnosticArray, '/diagnostics')

        def real_time_warnings():
            return [s for _, s in _status(diags, '/slow/')
                    if s.level == DiagnosticStatus.WARN and 'cannot keep real time' in s.message]

        # (on a loaded host a stall may be reported beside it, in the same message)
        assert wait_for(lambda: real_time_warnings(), 30)
        warn = real_time_warnings()[0]
        assert 'cannot keep real time' in warn.message and 'of 200' in warn.message
        achieved = float({kv.key: kv.value for kv in warn.values}['achieved real-time factor'])
        assert 0.5 < achieved < 180


@pytest.mark.parametrize('param, message', [
    ('sim.strain_limit:=0.0001', 'sim.strain_limit out of range'),
    ('filter.type:=notch', "filter.type 'notch' must be one of"),
    ('stamp:=gps', "stamp 'gps' must be one of auto, sim, wall"),
    ('scene:=no_such_scene', "unknown scene 'no_such_scene'"),
    ('publish_rate_hz:=30', 'publish_rate_hz'),
])
def test_bad_startup_parameters_exit_2_with_one_clear_line(param, message):
    node = NodeProcess(param, namespace='badstart')
    code, _, err = node.wait(30)
    assert code == 2
    assert 'Traceback' not in err and message in err


def test_a_band_needing_new_modes_keeps_the_stream_going():
    """
    sheet_100x100 starts with 32 modes.

    A band up to mode 99 makes the node compute more (in the worker process, at a lower priority
    than the stream's once it streams) and build the switch (in its change preparer's thread).
    The stream must go on meanwhile: in-process, the eigensolver held the interpreter for
    0.07-0.2 s at a time. (Rest modes: what the worker keeps off the stream is measured here;
    the derivative basis adds the band's derivatives to the request.)
    """
    with node_with_client('scene:=sheet_100x100', 'integrator:=average', 'filter.type:=lowpass',
                          'filter.by:=index', 'filter.high_mode:=15', 'modal.basis:=rest',
                          'stamp:=wall', namespace='grow') as (node, client):
        points = client.collect(PointCloud2, '/grow/points', qos=500)
        diags = client.collect(DiagnosticArray, '/diagnostics')
        assert wait_for(lambda: len(points) > 10, 60)
        time.sleep(3.0)                                  # a steady window to compare with
        start = time.monotonic()
        (result,) = client.set_parameters('grow/modal_spring', timeout=10.0,
                                          filter__high_mode=99)
        assert result.successful, result.reason          # at once: pending, or done

        def applied():
            for t, d in reversed(diags):
                if node_of(d.status[0]).startswith('/grow/') and t > start:
                    values = {kv.key: kv.value for kv in d.status[0].values}
                    return (values['modes stepped'] == '100'
                            and values['parameter changes pending'] == 'none')
            return False
        assert wait_for(applied, 180)
        done = time.monotonic()
        assert any(t > start and t < done for t, _ in points)   # frames during the work
        mine = [(t, {kv.key: kv.value for kv in d.status[0].values}) for t, d in diags
                if node_of(d.status[0]).startswith('/grow/')]
        assert int(mine[-1][1]['modes computed']) >= 100
        # the worker that computed them gives way to the stream: 10 below the node's priority
        assert spawned_niceness(node.proc.pid) == [min(niceness(node.proc.pid) + 10, 19)]

        def gaps(since: float, until: float) -> np.ndarray:
            """Return the longest gap between two frames of each report in a window."""
            return np.array([float(v['longest gap between frames (s)']) for t, v in mine
                             if since < t <= until])
        # the node's own account of its frames (a frame a busy test process is too slow to
        # take is overwritten in the publisher's history: a gap here, not in the stream)
        steady = gaps(start - 3.0, start)
        # while the modes are computed and the switch is made (after it, a run of 100 modes is a
        # heavier run: whether it keeps real time is reported apart, not a stall)
        working = gaps(start, done)
        received = np.array([stamp_s(m) for t, m in points if start < t <= done])
        print(f'longest gap a report while working {np.round(working, 3)} s (steady: '
              f'{np.round(steady, 3)} s; between frames received: '
              f'{np.diff(received).max():.3f} s)')
        # The eigensolver in the node's own interpreter once held it 0.07-0.2 s at each hold,
        # every time: most reports while working had a gap of several frames. Here a report's
        # gap is typically that of the steady stream; a busy machine's stall may lengthen one
        # report's (it did, to 0.185 s beside two busy processes), not most of them.
        bound = 5.0 * max(steady.max(), 1.0 / 60.0)
        typical = float(np.median(working))
        assert typical < bound, (
            typical, bound, [d.status[0].message for t, d in diags if start < t <= done])
        # and no report's gap is a hold of half a second or more
        assert working.max() < max(bound, 0.5), (working.max(), steady)


@pytest.mark.parametrize('scene, stage, never', [
    ('sheet_100x100', 'computing the 256 lowest modes', '256 modes ready'),
    ('sheet_316x316', 'modal derivatives: ', 'streaming sheet_316x316')])
@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM])
def test_a_signal_during_a_long_computation_at_startup_cancels_it(sig, scene, stage, never,
                                                                  tmp_path, monkeypatch):
    """
    A large start-up computes in the worker process for seconds (modes; then derivatives).

    Ctrl-C (SIGINT to the whole process group, as a terminal sends it) or SIGTERM (as a process
    manager sends it) must end the node cleanly without waiting for that computation, and
    leave nothing running behind it.
    """
    # a cache of its own: the modes solved, not read back from another test's run of the scene
    monkeypatch.setenv('MODAL_SPRING_ROS_CACHE', str(tmp_path / 'cache'))
    node = NodeProcess(f'scene:={scene}', namespace='startint')
    try:
        assert wait_for(lambda: stage in node.stderr(), 120)
        if sig == signal.SIGINT:
            os.killpg(node.proc.pid, sig)
        else:
            node.proc.send_signal(sig)
        code, _, err = node.wait(15)
        # nothing the node started outlives it (its worker, multiprocessing's resource tracker)
        left = process_group(node.proc.pid)
    finally:
        node.kill()
    assert code == 0, stderr_excerpt(err, 3000)
    assert 'Traceback' not in err
    assert never not in err                               # cancelled, not waited for
    assert left == [], left


def test_no_clock_unless_asked_and_one_line_once_streaming():
    node = NodeProcess(namespace='quiet')
    client = Client('quiet_client')
    try:
        points = client.collect(PointCloud2, '/quiet/points')
        clocks = client.collect(Clock, '/clock')
        assert wait_for(lambda: len(points) > 5, 30)

        def clock_publishers():
            return [i for i in client.node.get_publishers_info_by_topic('/clock')
                    if i.node_namespace == '/quiet']
        assert clock_publishers() == []                 # no /clock publisher at all
        (result,) = client.set_parameters('quiet/modal_spring', publish_clock=True)
        assert result.successful, result.reason
        assert wait_for(lambda: len(clocks) > 5, 10)    # created when asked for
        assert len(clock_publishers()) == 1
    finally:
        client.close()
        code, _, err = node.interrupt()
    assert code == 0, stderr_excerpt(err, 3000)
    lines = [x for x in err.splitlines() if 'streaming sheet_10x10' in x]
    assert len(lines) == 1, stderr_excerpt(err)
    assert ('streaming sheet_10x10 (100 particles; modal, allpass) on /quiet/points at 60 Hz, '
            "frame 'world'") in lines[0]


@pytest.mark.parametrize('policy, value, field, expected', [
    ('reliability', 'best_effort', 'reliability', ReliabilityPolicy.BEST_EFFORT),
    ('durability', 'transient_local', 'durability', DurabilityPolicy.TRANSIENT_LOCAL)])
def test_the_stream_s_qos_can_be_overridden_at_start(policy, value, field, expected):
    """
    A policy the node documents as overridable is offered as given (durability was ignored).

    History and depth are overridable too, but the graph does not show a writer's depth.
    """
    with node_with_client(f'qos_overrides./qos/points.publisher.{policy}:={value}',
                          namespace='qos') as (node, client):
        assert wait_for(lambda: client.node.get_publishers_info_by_topic('/qos/points'), 30)
        (info,) = client.node.get_publishers_info_by_topic('/qos/points')
        assert getattr(info.qos_profile, field) == expected


def test_two_nodes_of_one_name_on_one_domain_are_both_warned():
    first = NodeProcess(namespace='twin')
    second = NodeProcess(namespace='twin')
    client = Client('twin_client')
    try:
        diags = client.collect(DiagnosticArray, '/diagnostics')

        def warned():
            return [s for _, s in _status(diags, '/twin/') if s.level == DiagnosticStatus.WARN
                    and '1 other node named /twin/modal_spring on this domain' in s.message]
        # each of the two says so: on /diagnostics (where both statuses carry one name) and in
        # its own log
        warning = '1 other node named /twin/modal_spring'
        assert wait_for(lambda: len(warned()) >= 2 and all(
            warning in node.stderr() for node in (first, second)), 60)
        assert {kv.key: kv.value for kv in warned()[0].values}['nodes with this name'] == '2'
        code, _, err = second.interrupt()
        assert code == 0 and err.count(warning) == 1                  # once
        # the one left says it is alone again once the graph forgets the other: the graph is
        # the middleware's (the other's goodbye, or at the latest the end of its DDS lease), so
        # the node is judged from when the test's own view of the graph forgot it

        def namesakes_seen():
            return client.node.get_node_names_and_namespaces().count(('modal_spring', '/twin'))
        if not wait_for(lambda: namesakes_seen() == 1, 180):
            pytest.xfail('the middleware kept the departed node on the graph for 180 s '
                         '(its goodbye and lease both missed on this machine)')
        forgotten = time.monotonic()

        def alone():
            return [(t - forgotten, s.message, {kv.key: kv.value for kv in s.values}.get(
                'nodes with this name')) for t, s in _status(diags, '/twin/') if t > forgotten]
        # the node looks every NAMESAKE_CHECK_S (2 s) and reports every second; its own view
        # of the graph may keep the other until that one's DDS lease ends (Fast DDS: 20 s)
        # where the goodbye reached the test but not the node (once, on a busy machine)
        cleared = wait_for(lambda: any(named == '1' and 'other node' not in message
                                       for _, message, named in alone()), 60)
        if not cleared and alone() and alone()[-1][2] == '2':
            # the node still reports the other, from its own graph, three leases on: an entry
            # the middleware kept after the other left (ghost nodes, ros2/ros2#1413). How the
            # node clears its count when its graph does is tested without DDS (test_namesakes.py)
            pytest.xfail("the node's own graph kept the departed node 60 s after the test's "
                         'forgot it (a ghost entry of the middleware)')
        assert cleared, (alone()[-5:], stderr_excerpt(first.stderr()))
    finally:
        client.close()
        first.kill()
        second.kill()

"""Recording the live node and playing bags back, over real DDS."""
from __future__ import annotations

from pathlib import Path
import signal
import subprocess
import threading
import time

from helpers import BAGS
from modal_spring_ros.bags.files.reader import BagReader
from modal_spring_ros.bags.files.run_loading import load_run
from modal_spring_ros.bags.files.sim_time import simulation_times
from modal_spring_ros.bags.files.writer import BagError
from modal_spring_ros.ros.parameters import CLOCK_OFFSET
from modal_spring_ros.ros.tools import player as player_module
from modal_spring_ros.ros.tools.installed_messages import installed_message
from modal_spring_ros.ros.tools.resimulate import frame_times, parameter_changes, resimulate
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest
from ros_harness import (Client, console_script, frames_since, interrupted_inside, NodeProcess,
                         wait_for)
from sensor_msgs.msg import PointCloud2
from std_srvs.srv import Trigger

pytestmark = pytest.mark.ros


def _with_another_topic(tmp_path) -> Path:
    """Return the low-pass reference bag with a second topic no one here subscribes to."""
    from modal_spring_ros.bags.files.writer import BagWriter
    from std_msgs.msg import String
    source = BagReader(BAGS / 'sheet_10x10_lowpass_0_14')
    out = tmp_path / 'two_topics'
    with BagWriter(out) as writer:
        writer.add_topic('/points', 'sensor_msgs/msg/PointCloud2',
                         source.topics['/points'].offered_qos_profiles)
        writer.add_topic('/chatter', 'std_msgs/msg/String', '')
        for m in source.messages(['/points']):
            writer.write('/points', m.data, m.log_time_ns, m.publish_time_ns)
            writer.write_message('/chatter', String(data='hello'), m.log_time_ns,
                                 m.log_time_ns)
    return out


def _delivered_late(source: Path, out: Path, topic: str, delay_ns: int) -> Path:
    """Return a copy of the bag ``source`` whose messages on ``topic`` were received later."""
    from modal_spring_ros.bags.files.writer import BagWriter
    bag = BagReader(source)
    messages = sorted(((m.log_time_ns + (delay_ns if m.topic == topic else 0), m)
                       for m in bag.messages()), key=lambda pair: pair[0])
    with BagWriter(out, attachments=True) as writer:
        for name, info in bag.topics.items():
            writer.add_topic(name, info.type_name, info.offered_qos_profiles)
        for log_time, m in messages:
            writer.write(m.topic, m.data, log_time, m.publish_time_ns)
        writer.add_run_record(bag.run_record(), bag.scene())
    return out


def _flushed(bag: Path, topic: str) -> int:
    """Return how many messages on ``topic`` a bag being written holds so far (0: none yet)."""
    try:
        return sum(1 for _ in BagReader(bag).messages([topic]))
    except BagError:          # no file yet, or not one chunk closed in it
        return 0


def test_replay_delivers_exactly_the_recorded_messages_with_their_timing(tmp_path):
    bag = BagReader(_with_another_topic(tmp_path))
    recorded = list(bag.messages(['/points']))
    client = Client('replay_client')
    received: list[tuple[float, bytes]] = []
    # each message's time as the player wrote it (DDS's source timestamp): what this process,
    # busy or not, takes them at is no measure of the player's timing
    client.node.create_subscription(
        PointCloud2, '/replay/points',
        lambda data, info: received.append((info['source_timestamp'] * 1e-9, data)),
        500, raw=True)
    assert len(bag.topics) > 1                # only the clouds have a subscriber
    started = time.monotonic()
    player = subprocess.Popen([console_script('modal_spring_replay'), str(bag.path), '--rate',
                               '2.0', '--wait-for-subscribers', '--ros-args', '-r',
                               '/points:=/replay/points'], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True)
    try:
        out, err = player.communicate(timeout=60)
        assert player.returncode == 0, err
        # it waited for the clouds' subscriber, not for every topic's (30 s, then anyway)
        assert time.monotonic() - started < player_module.WAIT_S - 5.0
        assert wait_for(lambda: len(received) >= len(recorded), 5)
    finally:
        client.close()
    # exactly the recorded messages, in order (decoded: CDR padding bytes may differ)
    from rclpy.serialization import deserialize_message
    assert len(received) == len(recorded)
    assert [deserialize_message(d, PointCloud2) for _, d in received] == \
        [installed_message(bag, m) for m in recorded]
    sent = np.diff([m.log_time_ns * 1e-9 for m in recorded]) / 2.0       # --rate 2
    got = np.diff([t for t, _ in received])
    assert abs(got.sum() - sent.sum()) < 0.1 * sent.sum()
    assert np.median(np.abs(got - sent)) < 0.004


def test_replay_stops_cleanly_while_it_waits_for_subscribers():
    """Ctrl-C while nothing subscribes: the player ends at once, with no traceback."""
    bag = BAGS / 'sheet_10x10_lowpass_0_14'
    player = subprocess.Popen([console_script('modal_spring_replay'), str(bag),
                               '--wait-for-subscribers', '/points', '--ros-args', '-r',
                               '/points:=/nobody_listens/points'], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True)
    try:
        time.sleep(4.0)                     # imported, its node up, waiting
        assert player.poll() is None
        player.send_signal(signal.SIGINT)
        out, err = player.communicate(timeout=20)
    finally:
        if player.poll() is None:
            player.kill()
    assert player.returncode in (0, 130), err
    assert 'Traceback' not in err
    assert 'played 0 messages' in out or player.returncode == 130


def test_replay_refuses_to_wait_for_a_topic_it_does_not_play():
    bag = BAGS / 'sheet_10x10_lowpass_0_14'
    done = subprocess.run([console_script('modal_spring_replay'), str(bag),
                           '--wait-for-subscribers', '/elsewhere'], capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 2
    assert 'names /elsewhere, which is not played' in done.stderr


def _importing_numpy(pid: int) -> bool:
    """Tell whether a process has numpy's library mapped (its own code is being imported)."""
    try:
        return 'numpy' in (Path('/proc') / str(pid) / 'maps').read_text()
    except OSError:
        return False


@pytest.mark.skipif(not Path('/proc/self/maps').exists(), reason='reads /proc (Linux)')
@pytest.mark.parametrize('after_s', [0.0, 0.3, 0.8])
def test_a_replay_stopped_as_it_starts_ends_cleanly(after_s):
    """
    Ctrl-C at any moment of the start (the bag read, ROS coming up, the node made, playing).

    From the moment the program's own imports run: a Ctrl-C inside the interpreter's own start
    (its ``site`` module) is Python's to report, not the program's.
    """
    player = subprocess.Popen([console_script('modal_spring_replay'),
                               str(BAGS / 'sheet_10x10_lowpass_0_14'), '--loop'],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert wait_for(lambda: _importing_numpy(player.pid), 30)
    time.sleep(after_s)
    player.send_signal(signal.SIGINT)
    out, err = player.communicate(timeout=30)
    # 130: stopped before playing (as a shell reports Ctrl-C); 0: after, saying how many it
    # played; never a traceback
    assert player.returncode in (0, 130) and 'Traceback' not in err, err
    assert out.startswith('played ') == (player.returncode == 0), out


@pytest.mark.parametrize('tool', ['replay', 'record'])
def test_ctrl_c_as_a_tool_makes_its_publishers_or_subscriptions_ends_it_cleanly(tool, tmp_path):
    """
    Ctrl-C as the replay makes its publishers, or the recorder its subscriptions: a clean stop.

    rclpy's own handler shut ROS down under the publisher or subscription being made: a
    traceback. Now a signal asks the tool to stop: it stops at once, its bag closed.
    """
    if tool == 'replay':
        argv = ['modal_spring_ros.ros.tools.player', 'playback_profile',
                'modal_spring_ros.cli.modal_spring_replay', str(BAGS / 'sheet_10x10_lowpass_0_14'),
                '--loop']
    else:
        argv = ['modal_spring_ros.cli.modal_spring_record', 'Recorder',
                'modal_spring_ros.cli.modal_spring_record', '--output', str(tmp_path / 'bag'),
                '--wait-for-node', '20', '--ros-args', '-r', '__ns:=/nobody']
    done = interrupted_inside(*argv)      # the replay loops: it ends only when stopped
    assert done.returncode == 0 and 'Traceback' not in done.stderr, done.stderr[-3000:]
    if tool == 'record':
        # its wait for the node (20 s, then a warning) ended by the stop
        assert done.stdout.startswith('wrote ') and 'did not answer' not in done.stderr
        assert BagReader(tmp_path / 'bag').finalised


def test_recorder_captures_the_live_node_and_its_bag_resimulates(tmp_path):
    out = tmp_path / 'live'
    node = NodeProcess('publish_rate_hz:=30.0', namespace='rec')
    client = Client('rec_client')
    points = client.collect(PointCloud2, '/rec/points')
    recorder = None
    try:
        assert wait_for(lambda: len(points) > 3, 30)
        recorder = subprocess.Popen(
            [console_script('modal_spring_record'), '--output', str(out), '--node',
             '/rec/modal_spring',                   # the default topics, TF's included
             '--ros-args', '-r', '__ns:=/rec'],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        log: list[str] = []
        reader = threading.Thread(target=lambda: log.extend(iter(recorder.stderr.readline, '')),
                                  daemon=True)
        reader.start()
        assert wait_for(lambda: any('recording /rec/points' in line for line in log), 30)
        assert wait_for(lambda: any('parameters of node /rec/modal_spring and its scene' in line
                                    for line in log), 30)
        frames_since(points, time.monotonic(), 60, timeout=60)
        (result,) = client.set_parameters('rec/modal_spring', atomically=True,
                                          filter__type='lowpass', filter__high_hz=12.0)
        assert result.successful
        frames_since(points, time.monotonic(), 75, timeout=60)
        assert client.call(Trigger, '/rec/modal_spring/reset', Trigger.Request()).success
        frames_since(points, time.monotonic(), 45, timeout=60)
        recorder.send_signal(signal.SIGINT)
        recorder.wait(timeout=30)
        reader.join(timeout=5)
        err = ''.join(log)
        assert recorder.returncode == 0, err
        assert 'Traceback' not in err
    finally:
        client.close()
        node.kill()
        if recorder is not None and recorder.poll() is None:
            recorder.kill()
    bag = BagReader(out)
    assert bag.finalised and (out / 'metadata.yaml').exists()
    assert {'/rec/points', '/diagnostics', '/parameter_events', '/tf'} <= set(bag.topics)
    assert bag.topics['/tf'].count > 0
    assert bag.topics['/tf'].type_name == 'tf2_msgs/msg/TFMessage'
    assert bag.topics['/rec/points'].count > 30          # over a second of frames
    assert 'reliability: reliable' in bag.topics['/rec/points'].offered_qos_profiles
    record = bag.run_record()
    assert record['parameters']['scene'] == 'sheet_10x10'
    assert record['parameters']['filter.type'] == 'allpass'
    assert record['scene_archive'] == 'scene.npz'               # the full definition
    np.testing.assert_array_equal(bag.scene().rest_positions,
                                  load_scene('sheet_10x10').rest_positions)
    # header stamp (the node's clock: system time by default) as publish time, receive time as
    # log time
    first = next(bag.messages(['/rec/points']))
    stamp = bag.decode(first).header.stamp
    assert first.publish_time_ns == stamp.sec * 1_000_000_000 + stamp.nanosec
    assert first.log_time_ns > 1_600_000_000 * 10**9
    assert abs(first.log_time_ns - first.publish_time_ns) < 10**9
    # re-simulation: the same scene, parameters, change and reset give the recorded frames
    again = tmp_path / 'again'
    n = resimulate(out, again, topic='/rec/points')
    # each frame's simulation time, as published beside it on sim_time
    t_rec, x_rec = bag.points('/rec/points', simulation_times(bag, '/rec/points'))
    t_new, x_new = BagReader(again).points()
    assert n == len(t_rec) >= bag.topics['/rec/points'].count - 10   # both subscribed at once
    assert np.all(np.diff(t_rec) > 0)                # the reset did not send that time back
    np.testing.assert_array_equal(load_run(out, '/rec/points').t, t_rec)   # compared the same
    (moved,) = [(log, change[CLOCK_OFFSET]) for log, _, change
                in parameter_changes(bag, '/rec/modal_spring') if CLOCK_OFFSET in change]
    # the frames placed (those whose sim_time was recorded: the two topics' subscriptions
    # match at slightly different moments)
    after = np.array([log for log, _ in frame_times(bag, '/rec/points')]) > moved[0]
    assert 30 < after.sum() < n - 60
    # the time reached (a reset right after a frame moves the offset to that frame's own time),
    # and a step on (stamps are whole nanoseconds)
    assert t_rec[~after][-1] <= moved[1] + 1e-9 and moved[1] <= t_rec[after][0] + 1e-9
    # the re-run is stamped with simulation time: the recorded times less the offset
    # (a frame at the reset's own time is both the last before it and the first after it: its
    # place in the re-run follows the reset, its log time before the change's may not)
    at_reset = np.abs(t_rec - moved[1]) <= 1e-6
    placed = np.where(after | (at_reset & (np.abs(t_new) <= 1e-6)), t_rec - moved[1], t_rec)
    np.testing.assert_allclose(t_new, placed, atol=1e-6)
    err = np.linalg.norm((x_new - x_rec).reshape(n, -1), axis=1)
    before = err[: n // 4]                                   # well before the band change
    assert before.max() < 1e-5                               # float32 round-off
    assert err[after].max() < 1e-5                           # from rest again, as recorded
    # the band change where the node applied it (applied_parameter_events): every frame
    assert bag.topics['/rec/applied_parameter_events'].count == 1
    assert err.max() < 1e-5
    # however late the graph delivers /parameter_events (a busy machine: frames stepped with
    # the new band received before it), the same re-run; a recording placed by delivery alone
    # would apply the band two seconds (60 frames) late
    late = _delivered_late(out, tmp_path / 'late', '/parameter_events', 2 * 10**9)
    assert resimulate(late, tmp_path / 'late_again', topic='/rec/points') == n
    np.testing.assert_array_equal(BagReader(tmp_path / 'late_again').points()[1], x_new)


def test_frames_stamped_with_the_nodes_clock_need_their_sim_time():
    """A recording of the node's clock stamps without sim_time cannot be placed: it says so."""
    bag = BagReader(BAGS / 'sheet_10x10_full')         # no sim_time: stamps are simulation time
    frames = frame_times(bag, '/points')
    np.testing.assert_allclose([t for _, t in frames], bag.points('/points')[0])
    with pytest.raises(BagError, match='stamped with the node.s clock and the bag has no '
                                       '/sim_time'):
        frame_times(bag, '/points', stamped_in_sim_time=False)


def test_the_nodes_own_capture_resimulates_frame_for_frame(tmp_path):
    """
    record.bag.

    Every published frame straight to a bag, with the parameters and each change at the simulation
    time it took effect: the re-run reproduces all of it.
    """
    from ros_harness import node_with_client
    out = tmp_path / 'direct'
    with node_with_client(f'record.bag:={out}', 'publish_rate_hz:=30.0',
                          namespace='direct') as (node, client):
        points = client.collect(PointCloud2, '/direct/points')
        assert wait_for(lambda: len(points) > 20, 30)
        (r,) = client.set_parameters('direct/modal_spring', atomically=True,
                                     filter__type='bandpass', filter__low_hz=8.0,
                                     filter__high_hz=40.0)
        assert r.successful
        frames_since(points, time.monotonic(), 30, timeout=60)
        (r,) = client.set_parameters('direct/modal_spring', filter__gains='peak:12:4:12 30:40:-6')
        assert r.successful                              # an equalised run, faded in
        frames_since(points, time.monotonic(), 30, timeout=60)
        (r,) = client.set_parameters('direct/modal_spring', atomically=True, filter__gains='',
                                     method='full')
        assert r.successful
        frames_since(points, time.monotonic(), 20, timeout=60)
        assert client.call(Trigger, '/direct/modal_spring/reset', Trigger.Request()).success
        frames_since(points, time.monotonic(), 20, timeout=60)
    bag = BagReader(out)
    assert bag.finalised and bag.topics['/points'].count > 90
    assert bag.topics['/parameter_events'].count == 3
    again = tmp_path / 'again'
    n = resimulate(out, again)
    t_rec, x_rec = bag.points()
    t_new, x_new = BagReader(again).points()
    assert n == len(t_rec) and np.array_equal(t_new, t_rec)
    assert np.any(np.diff(t_rec) < 0)                       # the reset is in the recording
    np.testing.assert_allclose(x_new, x_rec, rtol=0, atol=2e-6)   # every frame


def test_a_recorder_killed_with_sigkill_leaves_a_readable_bag(tmp_path):
    from ros_harness import node_with_client
    out = tmp_path / 'killed'
    with node_with_client('publish_rate_hz:=60.0', namespace='kill') as (node, client):
        points = client.collect(PointCloud2, '/kill/points', qos=500)
        assert wait_for(lambda: len(points) > 10, 30)
        recorder = subprocess.Popen(
            [console_script('modal_spring_record'), '--output', str(out), '--topics', 'points',
             '--wait-for-node', '2', '--ros-args', '-r', '__ns:=/kill'],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        log: list[str] = []
        threading.Thread(target=lambda: log.extend(iter(recorder.stderr.readline, '')),
                         daemon=True).start()
        assert wait_for(lambda: any('recording /kill/points' in line for line in log), 30)
        # clouds of 1.7 kB: a second's 100 kB is far under one full chunk (768 kB), so only
        # the chunks closed each second reach the file; killed once more than 100 have (what
        # the recorder was sent is no measure: a busy machine delays its subscription)
        assert wait_for(lambda: _flushed(out, '/kill/points') > 100, 90)
        flushed = _flushed(out, '/kill/points')
        recorder.kill()
        recorder.wait(timeout=10)
    bag = BagReader(out)
    assert not bag.finalised and not (out / 'metadata.yaml').exists()
    messages = list(bag.messages(['/kill/points']))
    assert len(messages) >= flushed          # the kill lost nothing already in closed chunks
    stamps = [bag.decode(m).header.stamp for m in messages]   # every one decodes
    ns = [s.sec * 1_000_000_000 + s.nanosec for s in stamps]
    assert ns == sorted(ns) and len(set(ns)) == len(ns)      # in order, none twice


def test_the_nodes_capture_killed_with_sigkill_keeps_all_but_its_last_second(tmp_path):
    out = tmp_path / 'capture'
    node = NodeProcess(f'record.bag:={out}', namespace='capkill')
    client = Client('capkill_client')
    try:
        points = client.collect(PointCloud2, '/capkill/points', qos=500)
        assert wait_for(lambda: len(points) > 10, 30)
        # a chunk closes every second: killed once more than 100 frames have reached the file
        assert wait_for(lambda: _flushed(out, '/points') > 100, 90)
        flushed = _flushed(out, '/points')
        node.kill()
    finally:
        client.close()
        node.kill()
    bag = BagReader(out)
    stamps, frames = bag.points('/points')
    assert not bag.finalised
    # at most the open chunk (the last second's frames) is lost: every closed one is read
    assert len(frames) >= flushed and stamps[-1] > 1.5

"""
rosbag2 MCAP bags.

The format rosbag2 reads, independent readers, replay by re-simulation, crash safety, real rosbag2
files, and bad input.
"""
from __future__ import annotations

import contextlib
import importlib
import io
import os
import signal
import subprocess
import sys
import textwrap
import time

from helpers import BAGS, REAL_BAGS
from modal_spring_ros.bags.files.reader import BagReader
from modal_spring_ros.bags.files.reference_bags import RUNS
from modal_spring_ros.bags.files.writer import BagError, BagWriter
from modal_spring_ros.bags.messages.message_definitions import (DELIMITER, full_definition,
                                                                share_directory)
from modal_spring_ros.bags.messages.pointcloud import xyz
from modal_spring_ros.bags.messages.qos import profiles_from_yaml
from modal_spring_ros.cli.modal_spring_sim import main as sim_main
from modal_spring_ros.ros.tools.installed_messages import installed_message
from modal_spring_ros.ros.tools.resimulate import resimulate
from modal_spring_ros.scenes.files.writing import scene_to_dict
from modal_spring_ros.scenes.resources import load_scene
from modal_spring_ros.scenes.schema import scene_from_dict
import numpy as np
import pytest
from std_msgs.msg import String
import yaml

REAL = REAL_BAGS
# The real rosbag2 recordings sit beside the repository (CI has them): required under CI.
needs_real_bags = pytest.mark.skipif(
    not REAL.is_dir() and os.environ.get('CI') != 'true',
    reason=f'real rosbag2 bags not found at {REAL} (set MODAL_SPRING_REAL_BAGS)')


def _msg(pkg: str, name: str) -> str:
    return (share_directory(pkg) / 'msg' / f'{name}.msg').read_text()


def test_pointcloud2_schema_is_rosbag2s_concatenation_of_the_installed_msg_files():
    # rosbag2: root text, then each dependency (sorted, depth first, once) after a delimiter.
    expected = (_msg('sensor_msgs', 'PointCloud2')
                + '\n' + DELIMITER + 'MSG: sensor_msgs/PointField\n'
                + _msg('sensor_msgs', 'PointField')
                + '\n' + DELIMITER + 'MSG: std_msgs/Header\n' + _msg('std_msgs', 'Header')
                + '\n' + DELIMITER + 'MSG: builtin_interfaces/Time\n'
                + _msg('builtin_interfaces', 'Time'))
    assert full_definition('sensor_msgs/msg/PointCloud2') == expected
    bag = BagReader(BAGS / 'sheet_10x10_allpass')
    from mcap.reader import make_reader
    with open(bag.files[0], 'rb') as fh:
        schemas = make_reader(fh).get_summary().schemas
    (schema,) = schemas.values()
    assert schema.name == 'sensor_msgs/msg/PointCloud2' and schema.encoding == 'ros2msg'
    assert schema.data.decode() == expected


@needs_real_bags
def test_schema_matches_a_real_rosbag2_recording():
    """Against rosbag2's own ParameterEvent schema (only Time.msg's comments changed since)."""
    from mcap.reader import make_reader
    with open(REAL / 'only_topics' / 'only_topics.mcap', 'rb') as fh:
        summary = make_reader(fh).get_summary()
    real = next(s for s in summary.schemas.values()
                if s.name == 'rcl_interfaces/msg/ParameterEvent').data.decode()
    ours = full_definition('rcl_interfaces/msg/ParameterEvent')

    def sections(text):
        parts = text.split('\n' + DELIMITER)
        return {p.split('\n', 1)[0]: p for p in parts[1:]} | {'root': parts[0]}
    real_s, ours_s = sections(real), sections(ours)
    assert list(real_s) == list(ours_s)                  # same dependencies, same order
    for key in real_s:
        if key != 'MSG: builtin_interfaces/Time':
            assert real_s[key] == ours_s[key], key


REQUIRED_V9 = {'version', 'storage_identifier', 'duration', 'starting_time', 'message_count',
               'topics_with_message_count', 'compression_format', 'compression_mode',
               'relative_file_paths', 'files', 'custom_data', 'ros_distro'}


def test_metadata_yaml_has_every_key_rosbag2s_version_9_reader_requires():
    info = yaml.safe_load((BAGS / 'sheet_10x10_allpass' / 'metadata.yaml').read_text())[
        'rosbag2_bagfile_information']
    assert REQUIRED_V9 <= set(info)
    assert info['version'] == 9 and info['storage_identifier'] == 'mcap'
    assert info['ros_distro'] == 'jazzy' and isinstance(info['custom_data'], dict)
    assert isinstance(info['duration']['nanoseconds'], int)
    assert isinstance(info['starting_time']['nanoseconds_since_epoch'], int)
    (topic,) = info['topics_with_message_count']
    meta = topic['topic_metadata']
    assert set(meta) == {'name', 'type', 'serialization_format', 'offered_qos_profiles',
                         'type_description_hash'}
    assert meta['type'] == 'sensor_msgs/msg/PointCloud2' and meta['serialization_format'] == 'cdr'
    assert meta['type_description_hash'].startswith('RIHS01_')
    assert isinstance(meta['offered_qos_profiles'], str)       # a YAML string, as rosbag2
    (qos,) = yaml.safe_load(meta['offered_qos_profiles'])
    assert qos['history'] == 'keep_last' and qos['reliability'] == 'reliable'  # v9: names
    assert topic['message_count'] == info['message_count'] == 182
    (f,) = info['files']
    assert set(f) == {'path', 'starting_time', 'duration', 'message_count'}
    assert info['relative_file_paths'] == [f['path']] == ['sheet_10x10_allpass_0.mcap']


def test_mcap_records_are_what_rosbag2_writes():
    from mcap.reader import make_reader
    path = BAGS / 'sheet_10x10_allpass' / 'sheet_10x10_allpass_0.mcap'
    with open(path, 'rb') as fh:
        reader = make_reader(fh)
        assert reader.get_header().profile == 'ros2'
        summary = reader.get_summary()
        (channel,) = summary.channels.values()
        assert channel.message_encoding == 'cdr'
        assert set(channel.metadata) == {'offered_qos_profiles', 'topic_type_hash'}
        assert summary.statistics.message_count == 182 and summary.chunk_indexes
        assert all(c.message_index_offsets for c in summary.chunk_indexes)
        rosbag2 = [m for m in reader.iter_metadata() if m.name == 'rosbag2']
        assert len(rosbag2) == 2                     # at open and at close, as rosbag2
        final = yaml.safe_load(rosbag2[-1].metadata['serialized_metadata'])
        assert final['message_count'] == 182 and final['version'] == 9


@pytest.mark.parametrize('name', sorted(RUNS))
def test_resimulating_each_reference_bag_reproduces_its_frames(name, tmp_path):
    out = tmp_path / 'again'
    assert resimulate(BAGS / name, out) == 182
    t_ref, x_ref = BagReader(BAGS / name).points()
    t_new, x_new = BagReader(out).points()
    np.testing.assert_array_equal(t_new, t_ref)
    np.testing.assert_allclose(x_new, x_ref, rtol=0, atol=1e-6)   # float32 round-off
    assert np.abs(x_ref - x_ref[0]).max() > 1e-3                    # the frames do move


def test_independent_readers_decode_what_was_published(tmp_path):
    """
    Independent readers, rosbags (AnyReader) and mcap_ros2, read the bag.

    Rclpy decodes each payload to exactly the message that was written.
    """
    from modal_spring_ros.bags.files.capture import RunBagWriter
    from modal_spring_ros.core.config import SimulationConfig
    from modal_spring_ros.core.factory import build_simulation
    from modal_spring_ros.core.filter_band import FilterBand
    from modal_spring_ros.runs.run import record
    config = SimulationConfig(band=FilterBand('lowpass', high=20.0))
    sim = build_simulation(load_scene('sheet_10x10'), config)
    bag = RunBagWriter(tmp_path / 'bag', sim.model.scene, config, dt=sim.dt, frame_every=40,
                       duration=0.5)
    published = []

    def frame(t, positions):
        bag.frame(t, positions)
        from modal_spring_ros.bags.messages.pointcloud import to_pointcloud2
        from modal_spring_ros.bags.messages.stamps import to_time_msg
        from std_msgs.msg import Header
        published.append(to_pointcloud2(positions, sim.model.scene.rest_positions,
                                        Header(stamp=to_time_msg(t), frame_id='world')))
    record(sim, 0.5, frame_every=40, on_frame=frame)
    bag.close()
    reader = BagReader(tmp_path / 'bag')
    decoded = [installed_message(reader, m) for m in reader.messages()]
    assert decoded == published                                   # rclpy: equal messages
    # and from the bag's own definition, without ROS: the same clouds
    for m, message in zip(reader.messages(), published):
        np.testing.assert_array_equal(xyz(reader.decode(m)), xyz(message))

    from rosbags.highlevel import AnyReader
    from rosbags.typesys import get_typestore, Stores
    with AnyReader([tmp_path / 'bag'],
                   default_typestore=get_typestore(Stores.ROS2_JAZZY)) as r:
        (conn,) = r.connections
        assert conn.msgtype == 'sensor_msgs/msg/PointCloud2' and conn.msgcount == len(published)
        for (c, _, raw), want in zip(r.messages(), published):
            got = r.deserialize(raw, c.msgtype)
            assert (got.header.stamp.sec, got.header.stamp.nanosec) == (
                want.header.stamp.sec, want.header.stamp.nanosec)
            assert got.width == want.width and bytes(got.data) == bytes(want.data)
            assert [f.name for f in got.fields] == [f.name for f in want.fields]

    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    with open(reader.files[0], 'rb') as fh:
        items = list(make_reader(fh, decoder_factories=[DecoderFactory()])
                     .iter_decoded_messages())
    assert len(items) == len(published)
    for (_, _, _, got), want in zip(items, published):
        assert got.header.frame_id == 'world' and bytes(got.data) == bytes(want.data)


def test_a_killed_writer_leaves_every_complete_chunk_readable(tmp_path):
    """SIGKILL mid-run: every message before the last (unfinished) chunk is read back."""
    script = textwrap.dedent(f"""
        import sys
        from modal_spring_ros.bags.files.writer import BagWriter
        w = BagWriter({str(tmp_path / 'killed')!r}, chunk_size=4096)
        w.add_topic('/data', 'std_msgs/msg/String', '')
        from std_msgs.msg import String
        for i in range(100000):
            w.write_message('/data', String(data='message %06d ' % i + 'x' * 200), i, i)
            if i == 300:
                print('ready', flush=True)
    """)
    proc = subprocess.Popen([sys.executable, '-c', script], stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == 'ready'
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    reader = BagReader(tmp_path / 'killed')
    assert not reader.finalised
    got = [reader.decode(m).data[:14] for m in reader.messages()]
    # messages of ~230 bytes in 4 kB chunks: everything but the last chunk, in order
    assert len(got) >= 300 - 4096 // 200
    assert got == [f'message {i:06d}' for i in range(len(got))]


@needs_real_bags
def test_real_rosbag2_bags_are_read():
    only = BagReader(REAL / 'only_topics' / 'only_topics.mcap')
    assert only.topics['/parameter_events'].type_name == 'rcl_interfaces/msg/ParameterEvent'
    assert only.topics['/parameter_events'].count == 7 and only.topics['/rosout'].count == 0
    events = [only.decode(m) for m in only.messages(['/parameter_events'])]
    assert len(events) == 7 and all(e.node for e in events)
    cdr = BagReader(REAL / 'cdr_test')
    assert cdr.metadata['version'] == 7
    assert {t: i.count for t, i in cdr.topics.items()} == {'/test_topic': 3, '/array_topic': 4}
    assert len(list(cdr.messages())) == 7
    services = BagReader(REAL / 'bag_with_topics_and_service_events')
    assert sum(i.count for i in services.topics.values()) == 10
    assert services.topics['/test_service1/_service_event'].type_name == \
        'test_msgs/srv/BasicTypes_Event'
    assert len(list(services.messages())) == 10
    # a type installed nowhere here decodes from the bag's own definition (no ROS needed)
    strings = services.decode(next(services.messages(['/test_topic1'])))
    assert isinstance(strings.string_value, str) and isinstance(strings.bounded_string_value, str)
    # and is refused, by name, where ROS code would be handed its installed class
    with pytest.raises(BagError, match='test_msgs/msg/Strings is not installed'):
        installed_message(services, next(services.messages(['/test_topic1'])))
    qos = profiles_from_yaml(only.topics['/parameter_events'].offered_qos_profiles)
    assert len(qos) == 2                                         # version 8: integers


def test_qos_round_trips_through_the_v9_text():
    from modal_spring_ros.bags.messages.qos import profiles_to_yaml
    from rclpy.qos import QoSPresetProfiles
    for preset in (QoSPresetProfiles.SENSOR_DATA.value, QoSPresetProfiles.PARAMETER_EVENTS.value):
        (back,) = profiles_from_yaml(profiles_to_yaml([preset]))
        assert (back.reliability, back.durability, back.history, back.depth) == (
            preset.reliability, preset.durability, preset.history, preset.depth)


def _cli(module: str, *args: str) -> subprocess.CompletedProcess:
    """Return a console script's ``main`` run here (as its process would: exit status, output)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = importlib.import_module(module).main(list(args))
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
    return subprocess.CompletedProcess([module, *args], code, out.getvalue(), err.getvalue())


def test_bad_bags_and_outputs_fail_clearly_and_overwrite_nothing(tmp_path):
    missing = _cli('modal_spring_ros.cli.modal_spring_replay', str(tmp_path / 'nope'))
    assert missing.returncode == 2 and 'no such bag' in missing.stderr
    corrupt = tmp_path / 'corrupt.mcap'
    corrupt.write_bytes(os.urandom(4000))
    bad = _cli('modal_spring_ros.cli.modal_spring_compare', str(corrupt),
               str(BAGS / 'sheet_10x10_full'))
    assert bad.returncode == 2 and 'Traceback' not in bad.stderr and 'corrupt.mcap' in bad.stderr
    existing = tmp_path / 'existing'
    existing.mkdir()
    (existing / 'keep.txt').write_text('precious')
    again = _cli('modal_spring_ros.cli.modal_spring_replay', str(BAGS / 'sheet_10x10_full'),
                 '--resimulate', str(existing))
    assert again.returncode == 2 and 'already exists' in again.stderr
    assert [p.name for p in existing.iterdir()] == ['keep.txt']
    sim = _cli('modal_spring_ros.cli.modal_spring_sim', '--duration', '0.01', '--bag',
               str(tmp_path / 'no' / 'such' / 'bag'))
    assert sim.returncode == 2 and 'does not exist' in sim.stderr
    with pytest.raises(BagError, match='already exists'):
        BagWriter(existing)


@pytest.mark.slow
def test_compare_reports_zero_for_the_same_run_and_refuses_different_scenes(tmp_path):
    same = _cli('modal_spring_ros.cli.modal_spring_compare', str(BAGS / 'sheet_10x10_full'),
                str(BAGS / 'sheet_10x10_full'), '--json', str(tmp_path / 'c.json'),
                '--plot', str(tmp_path / 'c.png'))
    assert same.returncode == 0, same.stderr
    import json
    result = json.loads((tmp_path / 'c.json').read_text())
    assert result['rms_m'] == 0.0 and result['common_frames'] == 182
    assert (tmp_path / 'c.png').stat().st_size > 10_000
    _cli('modal_spring_ros.cli.modal_spring_compare', str(BAGS / 'sheet_10x10_lowpass_0_14'),
         str(BAGS / 'sheet_10x10_full'), '--json', str(tmp_path / 'l.json'))
    low = json.loads((tmp_path / 'l.json').read_text())
    assert 1e-4 < low['rel_l2_mean'] < 0.05      # close to the full run, but not equal
    npz = tmp_path / 'chain.npz'
    subprocess.run([sys.executable, '-m', 'modal_spring_ros.cli.modal_spring_sim',
                    '--scene', 'chain_2',
                    '--duration', '0.1', '--output', str(npz), '--quiet'], check=True,
                   capture_output=True)
    different = _cli('modal_spring_ros.cli.modal_spring_compare', str(npz),
                     str(BAGS / 'sheet_10x10_full'))
    assert different.returncode == 2
    assert 'different scenes: chain.npz has 3 particles' in different.stderr


def test_a_chunk_is_closed_once_it_is_old_full_or_not(tmp_path):
    writer = BagWriter(tmp_path / 'aging', chunk_seconds=0.2)
    writer.add_topic('/t', 'std_msgs/msg/String')
    for k in range(10):
        writer.write_message('/t', String(data=f'm{k}'), k)
    with pytest.raises(BagError, match='empty: the recording stopped before its first chunk'):
        BagReader(tmp_path / 'aging')                    # one small open chunk: not on disk
    time.sleep(0.25)
    writer.flush_if_due()                                # as the recorder's loop calls it
    on_disk = list(BagReader(tmp_path / 'aging').messages())
    assert len(on_disk) == 10                            # closed without waiting to fill
    writer.close()
    with pytest.raises(BagError, match=r'chunk size \(0\) must be a whole number of bytes'):
        BagWriter(tmp_path / 'zero', chunk_size=0)
    with pytest.raises(BagError, match=r'chunk seconds \(-1\) must be a positive number'):
        BagWriter(tmp_path / 'negative', chunk_seconds=-1)
    assert not (tmp_path / 'zero').exists() and not (tmp_path / 'negative').exists()


def _copy_bag(name: str, tmp_path):
    import shutil
    target = tmp_path / name
    shutil.copytree(BAGS / name, target)
    return target, target / f'{name}_0.mcap'


@pytest.mark.parametrize('metadata, message', [
    ('null\n', 'no rosbag2_bagfile_information mapping (the top level is NoneType)'),
    ('- 1\n- 2\n', 'no rosbag2_bagfile_information mapping (the top level is list)'),
    ('rosbag2_bagfile_information: {relative_file_paths: [null], storage_identifier: mcap}\n',
     'relative_file_paths must be a list of file names, got [None]'),
])
def test_damaged_metadata_is_one_line(metadata, message, tmp_path):
    bag, _ = _copy_bag('sheet_10x10_full', tmp_path)
    (bag / 'metadata.yaml').write_text(metadata)
    for tool in ('modal_spring_replay', 'modal_spring_compare'):
        args = [str(bag)] if tool == 'modal_spring_replay' else [str(bag), str(bag)]
        run = _cli(f'modal_spring_ros.cli.{tool}', *args)
        assert run.returncode == 2 and message in run.stderr, run.stderr
        assert run.stderr.count('\n') == 1 and 'Traceback' not in run.stderr


def test_a_damaged_cloud_is_named_and_never_compared_or_played(tmp_path):
    """
    16 bytes overwritten inside a cloud are found and named.

    16 bytes overwritten inside a cloud are found (the chunk's checksum, or the decoded cloud's NaN
    values) and named; nothing is compared or played.
    """
    bag, mcap = _copy_bag('sheet_10x10_full', tmp_path)
    raw = bytearray(mcap.read_bytes())
    at = raw.find(b'displacement') + 400                  # inside the first cloud's points
    raw[at:at + 16] = b'\xff' * 16                        # NaN float32s
    mcap.write_bytes(bytes(raw))
    compared = _cli('modal_spring_ros.cli.modal_spring_compare', str(bag),
                    str(BAGS / 'sheet_10x10_full'))
    assert compared.returncode == 2 and 'damaged' in compared.stderr, compared.stderr
    played = _cli('modal_spring_ros.cli.modal_spring_replay', str(bag))
    assert played.returncode == 2 and 'damaged' in played.stderr, played.stderr
    for run in (compared, played):
        assert run.stderr.count('\n') == 1 and 'Traceback' not in run.stderr
        assert 'nan' not in run.stdout.lower()


def test_a_cloud_with_non_finite_values_is_named(tmp_path):
    from modal_spring_ros.bags.messages.pointcloud import to_pointcloud2
    from std_msgs.msg import Header
    rest = load_scene('sheet_10x10').rest_positions
    writer = BagWriter(tmp_path / 'nan')
    writer.add_topic('/points', 'sensor_msgs/msg/PointCloud2')
    for k, bad in enumerate((False, True)):
        positions = rest.copy()
        if bad:
            positions[7, 1] = np.nan
        writer.write_message('/points', to_pointcloud2(positions, rest, Header()), k + 1)
    writer.close()
    reader = BagReader(tmp_path / 'nan')
    with pytest.raises(BagError, match=r'message on /points at log time 2 ns is damaged: its '
                                       r'cloud holds non-finite values'):
        reader.points('/points')
    with pytest.raises(BagError, match='log time 2 ns is damaged'):
        reader.check()


def test_reference_bags_start_at_the_date_they_were_made_and_keep_simulation_stamps():
    """
    Bag tools show a bag's start from its log times: not 1970.

    The stamps stay simulation time (0 to 3 s), spaced as the log times.
    """
    bag = BagReader(BAGS / 'sheet_10x10_lowpass_0_14')
    info = yaml.safe_load((bag.path / 'metadata.yaml').read_text())[
        'rosbag2_bagfile_information']
    assert info['starting_time']['nanoseconds_since_epoch'] > 1_700_000_000 * 10**9  # 2023 on
    logs = np.array([m.log_time_ns for m in bag.messages(['/points'])])
    stamps, _ = bag.points()
    assert stamps[0] < 0.1 and abs(stamps[-1] - 3.0) < 0.1
    np.testing.assert_allclose(np.diff(logs) * 1e-9, np.diff(stamps), atol=1e-9)


def test_the_summary_has_no_empty_index_group(tmp_path):
    """Every summary offset points at records (an empty AttachmentIndex group is flagged)."""
    from mcap.reader import make_reader
    from mcap.records import SummaryOffset
    from mcap.stream_reader import StreamReader
    with BagWriter(tmp_path / 'summary') as writer:
        writer.add_topic('/data', 'std_msgs/msg/String', '')
        for i in range(10):
            writer.write_message('/data', String(data=f'message {i}'), i, i)
    path = tmp_path / 'summary' / 'summary_0.mcap'
    with open(path, 'rb') as fh:
        offsets = [r for r in StreamReader(fh, skip_magic=False).records
                   if isinstance(r, SummaryOffset)]
    assert offsets and all(o.group_length > 0 for o in offsets), offsets
    with open(path, 'rb') as fh:
        assert len(list(make_reader(fh).iter_messages())) == 10


_CAPTURE = textwrap.dedent("""
    import sys
    from geometry_msgs.msg import PointStamped, PoseStamped
    from modal_spring_ros.bags.files.capture import RunBagWriter
    from modal_spring_ros.core.config import SimulationConfig
    from modal_spring_ros.core.factory import build_simulation
    from modal_spring_ros.scenes.resources import load_scene
    sim = build_simulation(load_scene('sheet_10x10'), SimulationConfig())
    bag = RunBagWriter(sys.argv[1], sim.model.scene, None, dt=sim.dt, frame_every=0,
                       duration=0.0, parameters={'scene': 'sheet_10x10'},
                       node='/robot/modal_spring')
    pose, click = PoseStamped(), PointStamped()
    pose.header.frame_id = click.header.frame_id = 'world'
    pose.pose.position.x, click.point.z = 0.45, -0.9
    for k in range(1, 31):
        sim.step(40)
        bag.frame(sim.time, sim.positions())
        if k % 10 == 0:
            bag.parameter_event(sim.time, {'filter.type': 'lowpass', 'filter.high_hz': 1.5 * k,
                                           'filter.by': 'hz', 'modal.max_modes': k})
            bag.record_input(sim.time, '/anchor_pose', pose)
            bag.record_input(sim.time, '/clicked_point', click)
    bag.close()
""")


@pytest.mark.slow
def test_a_nodes_capture_is_the_same_bytes_in_every_process_and_strict_readers_take_it(
        tmp_path):
    """
    The messages a capture serializes itself are canonical CDR.

    No trailing bytes (rosbags checks the size of every message) and zeroed padding: the same
    run captured in two processes gives the same payloads, byte for byte.
    """
    from rosbags.typesys import get_typestore, Stores
    payloads = []
    for name in ('first', 'second'):
        subprocess.run([sys.executable, '-c', _CAPTURE, str(tmp_path / name)], check=True,
                       timeout=120)
        reader = BagReader(tmp_path / name)
        payloads.append([(m.topic, bytes(m.data)) for m in reader.messages()])
    assert payloads[0] == payloads[1]
    topics = [topic for topic, _ in payloads[0]]
    assert topics.count('/parameter_events') == 3 and topics.count('/points') == 30
    assert topics.count('/anchor_pose') == 3 and topics.count('/clicked_point') == 3
    store = get_typestore(Stores.ROS2_JAZZY)
    types = {t: info.type_name for t, info in reader.topics.items()}
    for topic, data in payloads[0]:
        msg = store.deserialize_cdr(data, types[topic])      # raises on any stray byte
        assert store.serialize_cdr(msg, types[topic]) == data   # and its padding is zeros
    event = store.deserialize_cdr(next(d for t, d in payloads[0] if t == '/parameter_events'),
                                  'rcl_interfaces/msg/ParameterEvent')
    assert event.node == '/robot/modal_spring'
    assert [p.name for p in event.changed_parameters] == [
        'filter.type', 'filter.high_hz', 'filter.by', 'modal.max_modes']


def test_a_run_with_colliders_is_recorded_and_resimulated_frame_for_frame(tmp_path):
    """The scene's colliders and friction go into the bag; the re-run touches as the run did."""
    scene = tmp_path / 'table.yaml'
    data = scene_to_dict(load_scene('sheet_10x10'))
    data['anchor_motion'] = [{'axis': 'z', 'amplitude': 0.025, 'frequency_hz': 1.0,
                              'ramp_s': 0.2}]
    data['contact'] = {'friction': 0.3, 'colliders': [
        {'shape': 'plane', 'point': [0, 0, -0.915], 'normal': [0, 0, 1]},
        {'shape': 'sphere', 'center': [0.45, 0.0, -0.925], 'radius': 0.02}]}
    scene.write_text(yaml.safe_dump(data))
    bag = tmp_path / 'run'
    assert sim_main(['--scene', str(scene), '--duration', '1', '--frame-every', '20',
                     '--quiet', '--bag', str(bag)]) == 0
    kept = BagReader(bag).scene()
    assert kept.contact.to_dict() == scene_from_dict(data).contact.to_dict()
    out = tmp_path / 'again'
    frames = resimulate(bag, out)
    t_ref, x_ref = BagReader(bag).points()
    t_new, x_new = BagReader(out).points()
    assert frames == len(t_ref) and frames > 50
    np.testing.assert_array_equal(t_new, t_ref)
    np.testing.assert_allclose(x_new, x_ref, rtol=0, atol=1e-6)
    assert x_ref[:, :, 2].min() > -0.915 - 1e-3                    # held on the table

"""
A killed recording made readable by every reader: ``modal_spring_reindex``.

A writer killed before it closed leaves an MCAP file without summary or footer and a folder
without ``metadata.yaml``: mcap's indexed reader, its streaming reader and rosbags all refuse
it. Reindexed, all three read every message the project's own reader streams from the killed
file, byte for byte, with the run's records and scene; a finalised bag is left as it was.
"""
from __future__ import annotations

import hashlib
from pathlib import Path
import shutil
import signal
import subprocess
import time

from helpers import REAL_BAGS
from mcap.reader import make_reader, NonSeekingReader
from modal_spring_ros.bags.files.reader import BagReader
from modal_spring_ros.bags.files.reindex import reindex
from modal_spring_ros.bags.files.writer import BagError, BagWriter
from modal_spring_ros.bags.messages.qos import profiles_to_yaml
import pytest
from rclpy.qos import QoSProfile, ReliabilityPolicy
from ros_harness import Client, console_script, NodeProcess, wait_for
from rosbags.rosbag2 import Reader as RosbagsReader
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import String
import yaml

#: the two topics' offered QoS, as the recorder stores them
QOS_A = profiles_to_yaml([QoSProfile(depth=10)])
QOS_B = profiles_to_yaml([QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)])


def readers(bag: Path) -> dict[str, int]:
    """Return how many messages each outside reader reads from ``bag`` (-1: it refused)."""
    counts = {}
    (mcap_file,) = sorted(bag.glob('*.mcap'))
    for name, make in (('indexed', make_reader), ('streaming', NonSeekingReader)):
        try:
            with open(mcap_file, 'rb') as fh:
                counts[name] = sum(1 for _ in make(fh).iter_messages())
        except Exception:
            counts[name] = -1
    try:
        with RosbagsReader(bag) as r:
            counts['rosbags'] = sum(1 for _ in r.messages())
    except Exception:
        counts['rosbags'] = -1
    return counts


def streamed(bag: Path) -> list[tuple]:
    """Return every message the project's reader reads, as (topic, log, publish, bytes)."""
    return [(m.topic, m.log_time_ns, m.publish_time_ns, m.data)
            for m in BagReader(bag).messages()]


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def written_bag(folder: Path, messages: int = 400) -> Path:
    """Write a closed bag of two topics, a run record and a scene-like attachment."""
    with BagWriter(folder, chunk_size=2048) as w:
        w.add_topic('/a', 'std_msgs/msg/String', QOS_A)
        w.add_topic('/b', 'std_msgs/msg/String', QOS_B)
        w.add_run_record({'source': 'test', 'value': 3})
        for i in range(messages):
            w.write_message('/a' if i % 3 else '/b', String(data=f'message {i:05d}'),
                            1_000 + i, 2_000 + i)
    return folder


@pytest.mark.parametrize('kept', [0.35, 0.8, 0.999])
def test_a_bag_cut_anywhere_is_read_whole_by_every_reader_once_reindexed(tmp_path, kept):
    whole = written_bag(tmp_path / 'whole')
    killed = tmp_path / 'killed'
    killed.mkdir()
    data = (whole / 'whole_0.mcap').read_bytes()
    (killed / 'killed_0.mcap').write_bytes(data[:int(len(data) * kept)])   # no metadata.yaml
    before = streamed(killed)
    assert 50 < len(before) <= 400          # (cut in the summary: every message is there)
    assert readers(killed) == {'indexed': -1, 'streaming': -1, 'rosbags': -1}
    (report,) = reindex(killed)
    assert report.rewritten and report.messages == len(before) and report.topics == 2
    assert 'ends before its footer' in report.describe()
    n = len(before)
    assert readers(killed) == {'indexed': n, 'streaming': n, 'rosbags': n}
    assert streamed(killed) == before                        # the same bytes and times
    assert before == streamed(whole)[:n]
    reader = BagReader(killed)
    assert reader.finalised and reader.run_record()['value'] == 3
    info = yaml.safe_load((killed / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    counts = {t['topic_metadata']['name']: t['message_count']
              for t in info['topics_with_message_count']}
    assert counts == {'/a': sum(t == '/a' for t, *_ in before),
                      '/b': sum(t == '/b' for t, *_ in before)}
    assert info['relative_file_paths'] == ['killed_0.mcap'] and info['message_count'] == n
    assert {t['topic_metadata']['offered_qos_profiles']
            for t in info['topics_with_message_count']} == {QOS_A, QOS_B}
    again = digest(killed / 'killed_0.mcap')
    (report,) = reindex(killed)                              # finalised now: left as it is
    assert not report.rewritten and digest(killed / 'killed_0.mcap') == again


def test_a_finalised_bag_is_left_as_it_was_and_gets_the_metadata_it_lacks(tmp_path):
    whole = written_bag(tmp_path / 'whole')
    (whole / 'metadata.yaml').unlink()
    before = digest(whole / 'whole_0.mcap')
    (report,) = reindex(whole)
    assert not report.rewritten and report.messages == 400
    assert digest(whole / 'whole_0.mcap') == before
    assert readers(whole) == {'indexed': 400, 'streaming': 400, 'rosbags': 400}


@pytest.mark.skipif(not REAL_BAGS.is_dir(), reason=f'no real rosbag2 bags at {REAL_BAGS}')
def test_a_real_rosbag2_recording_cut_short_reindexes(tmp_path):
    source = REAL_BAGS / 'cdr_test'
    (mcap_file,) = sorted(source.glob('*.mcap'))
    cut = tmp_path / 'cdr_test'
    cut.mkdir()
    data = mcap_file.read_bytes()
    (cut / mcap_file.name).write_bytes(data[:int(len(data) * 0.6)])
    (report,) = reindex(cut)
    counts = readers(cut)
    assert report.rewritten and counts['indexed'] == counts['rosbags'] == report.messages
    assert streamed(cut) == streamed(source)[:report.messages]


def test_what_is_not_a_recording_is_refused_by_name(tmp_path):
    (tmp_path / 'junk.mcap').write_bytes(b'not an mcap file at all')
    with pytest.raises(BagError, match=r'junk\.mcap: not an MCAP file: .*invalid magic'):
        reindex(tmp_path / 'junk.mcap')
    (tmp_path / 'empty').mkdir()
    with pytest.raises(BagError, match=r'empty: no \.mcap file in the bag'):
        reindex(tmp_path / 'empty')
    with pytest.raises(BagError, match='no such bag'):
        reindex(tmp_path / 'missing')


@pytest.mark.slow
def test_a_headless_run_killed_while_it_writes_reindexes_with_the_console_script(tmp_path):
    bag = tmp_path / 'run'
    proc = subprocess.Popen([console_script('modal_spring_sim'), '--duration', '60',
                             '--frame-every', '10', '--quiet', '--bag', str(bag)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        mcap_file = bag / 'run_0.mcap'
        assert wait_for(lambda: mcap_file.exists() and mcap_file.stat().st_size > 2_000_000, 120)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(30)
    before = streamed(bag)
    assert readers(bag)['indexed'] == -1 and not (bag / 'metadata.yaml').exists()
    done = subprocess.run([console_script('modal_spring_reindex'), str(bag)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith(f'{bag}: run_0.mcap: {len(before)} messages on 1 topics')
    n = len(before)
    assert readers(bag) == {'indexed': n, 'streaming': n, 'rosbags': n}
    assert BagReader(bag).scene() is not None                  # the run's scene kept


@pytest.mark.ros
def test_a_node_killed_while_it_captures_leaves_a_bag_every_reader_reads_once_reindexed(
        tmp_path):
    bag = tmp_path / 'capture'
    node = NodeProcess(f'record.bag:={bag}', namespace='killed')
    try:
        client = Client('killed_client')
        try:
            points = client.collect(PointCloud2, '/killed/points', qos=100)
            assert wait_for(lambda: len(points) > 60, 60)
            time.sleep(1.5)                   # a chunk closes every second
        finally:
            client.close()
    finally:
        node.kill()                           # SIGKILL: the capture is never closed
    before = streamed(bag)
    assert len(before) > 30 and readers(bag)['rosbags'] == -1
    reindex(bag)
    n = len(before)
    assert readers(bag) == {'indexed': n, 'streaming': n, 'rosbags': n}
    assert streamed(bag) == before
    shutil.rmtree(bag)

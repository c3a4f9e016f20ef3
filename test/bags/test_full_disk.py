"""
A full disk while writing a bag or a run: one clear error, what was written stays readable.

The disk fills at a chosen byte (a file whose writes fail with ENOSPC past a budget, as a full
tmpfs does), for the writer, ``modal_spring_sim --bag/--output`` and the node's capture.
"""
from __future__ import annotations

from helpers import fill_disk_after
from modal_spring_ros.bags.files.reader import BagReader
from modal_spring_ros.bags.files.writer import BagError, BagWriter
from modal_spring_ros.cli.modal_spring_sim import main as sim_main
import pytest
from std_msgs.msg import String


@pytest.fixture
def disk_full_after(monkeypatch):
    """Make the bag writer's and numpy's files fill up after ``budget`` bytes."""
    return lambda budget: fill_disk_after(monkeypatch, budget)


def test_the_writer_stops_with_one_error_and_its_chunks_stay_readable(tmp_path, disk_full_after):
    disk_full_after(60_000)
    writer = BagWriter(tmp_path / 'full', chunk_size=4096)
    writer.add_topic('/data', 'std_msgs/msg/String', '')
    written = 0
    with pytest.raises(BagError, match='cannot write: No space left on device'):
        for i in range(10_000):
            writer.write_message('/data', String(data=f'message {i:06d} ' + 'x' * 200), i, i)
            written += 1
    with pytest.raises(BagError, match='not written to any more: cannot write: No space'):
        writer.write_message('/data', String(data='again'), 10**6, 10**6)
    with pytest.raises(BagError, match='cannot write'):
        writer.close()
    reader = BagReader(tmp_path / 'full')
    got = [reader.decode(m).data[:14] for m in reader.messages()]
    # lost: at most the chunk the disk filled in and the one still open (4 kB, ~17 each)
    assert written > 100 and len(got) >= written - 2 * (4096 // 230 + 1)
    assert got == [f'message {i:06d}' for i in range(len(got))]


@pytest.mark.parametrize('option', ['--bag', '--output'])
def test_the_headless_run_says_one_line_and_leaves_no_half_written_file(
        tmp_path, disk_full_after, capsys, option):
    disk_full_after(200_000)
    target = tmp_path / ('run' if option == '--bag' else 'run.npz')
    with pytest.raises(SystemExit) as info:
        sim_main(['--scene', 'sheet_10x10', '--duration', '2', '--quiet', option, str(target)])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and 'No space left on device' in err and 'Traceback' not in err
    assert not target.exists()                       # nothing truncated is left behind


def test_a_bag_name_too_long_for_the_file_system_is_refused_up_front(tmp_path, capsys):
    target = tmp_path / ('b' * 300)
    with pytest.raises(SystemExit) as info:
        sim_main(['--scene', 'sheet_10x10', '--duration', '0.01', '--quiet', '--bag',
                  str(target)])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and 'too long for the file system' in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.ros
def test_the_recorder_on_a_full_disk_says_one_line(tmp_path, monkeypatch, capsys):
    """
    The error is said once: finalising the bag on the same full disk raises it again.

    The disk fills while the run record is written; closing the bag then fails the same way.
    """
    import ros_harness  # noqa: F401 (this session's DDS domain, loopback discovery)
    from modal_spring_ros.cli.modal_spring_record import main as record_main

    def full(self, *args, **kwargs):
        raise BagError(f'{self.directory}: cannot write: No space left on device')
    monkeypatch.setattr(BagWriter, 'add_run_record', full)
    monkeypatch.setattr(BagWriter, 'close', full)
    with pytest.raises(SystemExit) as info:
        record_main(['--output', str(tmp_path / 'rec'), '--duration', '0.2',
                     '--wait-for-node', '0.1', '--node', '/nobody_here'])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert 'No space left on device' in err and 'Traceback' not in err
    assert err.count('modal_spring_record: error:') == 1

"""
Output files are claimed before the work.

A target that cannot be written, or that is an input or another output of the same command, is
refused at once with one line, and a failed command leaves no file behind.
"""
from __future__ import annotations

import os
import shutil
import stat

from helpers import BAGS
from modal_spring_ros.cli import modal_spring_compare, modal_spring_sim
import numpy as np
import pytest

FULL = str(BAGS / 'sheet_10x10_full')


def _error(main, argv, capsys) -> str:
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and 'Traceback' not in err, err
    return err


@pytest.mark.parametrize('target, message', [
    ('/proc/version', '--output /proc/version: cannot write'),      # read-only file system
    ('/dev/full', '--output /dev/full: cannot write: No space left on device'),
    ('x' * 300 + '.npz', 'cannot write: File name too long'),
    ('missing/folder/run.npz', '--output missing/folder/run.npz: folder missing/folder does '
                               'not exist'),
])
def test_an_output_that_cannot_be_written_fails_before_the_run(target, message, tmp_path,
                                                               capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    kind = os.stat(target).st_mode if os.path.exists(target) else None
    err = _error(modal_spring_sim.main, ['--duration', '0.01', '--quiet', '--output', target],
                 capsys)
    assert message in err
    assert list(tmp_path.iterdir()) == []               # nothing left behind
    if kind is not None:                                 # and what was there is still there
        assert stat.S_IFMT(os.stat(target).st_mode) == stat.S_IFMT(kind)


def test_output_and_bag_may_not_be_the_same_path(tmp_path, capsys):
    same = str(tmp_path / 'run')
    err = _error(modal_spring_sim.main, ['--duration', '0.01', '--quiet', '--output', same,
                                         '--bag', same], capsys)
    assert f'--output {same}: is also --bag' in err
    assert list(tmp_path.iterdir()) == []


def test_compare_never_overwrites_its_input(tmp_path, capsys):
    run = tmp_path / 'a.npz'
    assert modal_spring_sim.main(['--duration', '0.02', '--quiet', '--output', str(run)]) == 0
    before = run.read_bytes()
    capsys.readouterr()
    err = _error(modal_spring_compare.main, [str(run), FULL, '--json', str(run)], capsys)
    assert f'--json {run}: is also run A' in err
    assert run.read_bytes() == before


def test_a_failed_comparison_leaves_no_output_file(tmp_path, capsys):
    chain = tmp_path / 'chain.npz'
    assert modal_spring_sim.main(['--scene', 'chain_2', '--duration', '0.02', '--quiet',
                                  '--output', str(chain)]) == 0
    capsys.readouterr()
    out = tmp_path / 'c.json'
    err = _error(modal_spring_compare.main, [str(chain), FULL, '--json', str(out)], capsys)
    assert 'different scenes' in err
    assert not out.exists()


def test_a_run_without_room_for_its_frames_is_refused_before_it_starts(tmp_path, capsys,
                                                                       monkeypatch):
    """Its frames, its disk's free space and a --frame-every that fits are named; no file."""
    out = tmp_path / 'long.npz'
    free = shutil.disk_usage(tmp_path).free
    # sheet_10x10 over 2 s at 0.5 ms: 4,001 frames of 100 particles, 9.6 MB
    room = _usage_with_free(monkeypatch, 3_000_000)
    err = _error(modal_spring_sim.main, ['--method', 'full', '--duration', '2', '--output',
                                         str(out), '--quiet'], capsys)
    assert room.asked and all(os.path.samefile(p, tmp_path) for p in room.asked), room.asked
    assert f'--output {out}: the run keeps 4,001 frames of 100 particles' in err
    assert 'free: keep fewer frames (--frame-every 4 or more)' in err
    assert not out.exists()
    room.free = free                      # --frame-every 4 fits: it runs and writes
    assert modal_spring_sim.main(['--method', 'full', '--duration', '2', '--frame-every', '4',
                                  '--output', str(out), '--quiet']) == 0
    assert np.load(out)['positions'].shape == (1001, 100, 3)


def _usage_with_free(monkeypatch, free: int):
    """Make shutil.disk_usage say ``free`` bytes are free; return what records the calls."""
    class Usage:
        asked: list[str] = []

        def __call__(self, path):
            self.asked.append(os.fspath(path))
            return real(path)._replace(free=self.free)
    real, usage = shutil.disk_usage, Usage()
    usage.free = free
    monkeypatch.setattr(shutil, 'disk_usage', usage)
    return usage

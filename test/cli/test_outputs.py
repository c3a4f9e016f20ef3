"""
Output files are claimed before the work.

A target that cannot be written, or that is an input or another output of the same command, is
refused at once with one line, and a failed command leaves no file behind.
"""
from __future__ import annotations

import os
import stat

from helpers import BAGS
from modal_spring_ros.cli import modal_spring_compare, modal_spring_sim
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

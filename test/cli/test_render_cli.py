"""
``modal_spring_render``: a run drawn as a person would look at it.

The reference bags become an animated GIF and a strip of snapshots; what cannot be drawn is one
line, and leaves no file behind.
"""
from __future__ import annotations

from helpers import BAGS
from modal_spring_ros.bags.files.run_loading import load_run
from modal_spring_ros.cli import modal_spring_render
from modal_spring_ros.runs.rendering import frame_indices, view_axes
import numpy as np
from PIL import Image
import pytest

ALLPASS = BAGS / 'sheet_10x10_allpass'


def test_a_bag_becomes_an_animation_of_the_sheet_moving(tmp_path, capsys):
    out = tmp_path / 'sheet.gif'
    assert modal_spring_render.main([str(ALLPASS), '--output', str(out), '--fps', '10',
                                     '--duration', '1.0']) == 0
    assert 'wrote' in capsys.readouterr().out
    with Image.open(out) as gif:
        assert gif.n_frames == 11                    # 0.0, 0.1 ... 1.0 s
        frames = []
        for k in (0, 10):
            gif.seek(k)
            frames.append(np.asarray(gif.convert('RGB'), dtype=float))
    assert frames[0].std() > 10.0                    # something is drawn
    assert np.abs(frames[1] - frames[0]).mean() > 0.5   # and it moves


def test_snapshots_are_a_strip_and_the_sheet_hangs_upright(tmp_path):
    out = tmp_path / 'sheet.png'
    assert modal_spring_render.main([str(ALLPASS), '--output', str(out), '--snapshots',
                                     '4']) == 0
    with Image.open(out) as png:
        width, height = png.size
    assert width > 2.5 * height                      # four pictures side by side
    run = load_run(ALLPASS)
    assert view_axes(run) == (0, 2)                  # x across, z up: the sheet's own plane


def test_frames_are_picked_at_the_rate_asked_for():
    t = np.arange(0.0, 3.0, 1.0 / 60.0)
    picked = frame_indices(t, 20.0, 0.5, 1.0)
    np.testing.assert_allclose(np.diff(t[picked]), 0.05, atol=1.0 / 60.0)
    assert t[picked[0]] == pytest.approx(0.5, abs=1.0 / 60.0)
    assert t[picked[-1]] == pytest.approx(1.5, abs=1.0 / 60.0)


@pytest.mark.parametrize('argv, message', [
    (['--output', 'sheet.jpg'], "cannot tell the picture's format from its name"),
    (['--output', 'sheet.gif', '--start', '10'], 'no frame between 10 s'),
    (['--output', 'sheet.gif', '--fps', '0'], '--fps must be more than 0'),
    (['--output', 'sheet.png', '--snapshots', '0'], '--snapshots must be 1 to 24'),
])
def test_what_cannot_be_drawn_is_one_line_and_leaves_nothing(argv, message, tmp_path, capsys,
                                                             monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as info:
        modal_spring_render.main([str(ALLPASS), *argv])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert message in err and 'Traceback' not in err, err
    assert list(tmp_path.iterdir()) == []


def test_the_run_itself_is_never_overwritten(tmp_path, capsys):
    run = tmp_path / 'run.mcap'
    run.write_bytes(next(ALLPASS.glob('*.mcap')).read_bytes())
    before = run.read_bytes()
    with pytest.raises(SystemExit):
        modal_spring_render.main([str(run), '--output', str(run)])
    assert 'is also the run' in capsys.readouterr().err
    assert run.read_bytes() == before

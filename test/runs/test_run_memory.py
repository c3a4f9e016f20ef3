"""
A run too large to compare in memory is refused before it is read.

Sizes are read from the run's own file (an ``.npz`` array header, a bag's message count and
its first cloud) and checked against what a comparison holds
(:mod:`modal_spring_ros.runs.run_memory`).
"""
from __future__ import annotations

from helpers import BAGS
from modal_spring_ros.bags.files.reader import BagReader
from modal_spring_ros.cli import modal_spring_compare, modal_spring_sim
from modal_spring_ros.runs import run_memory
from modal_spring_ros.runs.comparison import load_npz_run, RunError
from modal_spring_ros.runs.run_memory import RunTooLarge, WORKING_COPIES
import pytest


@pytest.fixture(scope='module')
def chain_run(tmp_path_factory):
    """chain_2 over 0.02 s at its 1 ms step: 21 frames of 3 particles (1,512 bytes)."""
    path = tmp_path_factory.mktemp('runs') / 'chain.npz'
    assert modal_spring_sim.main(['--scene', 'chain_2', '--duration', '0.02', '--quiet',
                                  '--output', str(path)]) == 0
    return path


def test_a_run_within_the_budget_loads_and_one_beyond_is_refused_unread(chain_run):
    assert load_npz_run(chain_run, budget=1512).positions.shape == (21, 3, 3)
    with pytest.raises(RunError) as refused:
        load_npz_run(chain_run, budget=1000)
    said = str(refused.value)
    assert f'{chain_run}: its positions take 1.51e-06 GB (21 frames of 3 particles)' in said
    assert '--frame-every 2 or more' in said and f'about {WORKING_COPIES} arrays' in said


def test_a_bag_is_refused_by_its_message_count_before_its_clouds_are_read(monkeypatch):
    """sheet_10x10_full: its count and first cloud say what its positions would take."""
    bag = BagReader(BAGS / 'sheet_10x10_full')
    stamps, frames = bag.points('/points')
    count = bag.topics['/points'].count
    assert len(frames) == count
    decoded = []
    original = bag.decode
    monkeypatch.setattr(bag, 'decode', lambda m: decoded.append(1) or original(m))
    with pytest.raises(RunTooLarge, match=rf'{count:,} frames of 100 particles'):
        bag.points('/points', max_bytes=frames.nbytes - 1)
    assert len(decoded) == 1              # refused at its first cloud
    assert bag.points('/points', max_bytes=frames.nbytes)[1].shape == frames.shape


def test_compare_says_a_run_is_too_large_for_the_memory_left(chain_run, monkeypatch, capsys):
    monkeypatch.setattr(run_memory, 'available_memory', lambda: WORKING_COPIES * 1000)
    with pytest.raises(SystemExit) as ended:
        modal_spring_compare.main([str(chain_run), str(chain_run)])
    assert ended.value.code == 2
    err = capsys.readouterr().err
    assert 'its positions take 1.51e-06 GB (21 frames of 3 particles), more than a ' \
        'comparison can hold beside the other run in the 1.2e-05 GB free' in err, err

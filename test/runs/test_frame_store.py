"""
The frames a run keeps: held once, in a file where memory should not hold them.

The same run kept in memory and in a file gives the same ``.npz``; a large run's memory stays
what one copy of its frames takes (it took three: a list, the stacked array, a cast copy).
"""
from __future__ import annotations

import os
import tracemalloc

from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.runs import frame_store, run
from modal_spring_ros.runs.frame_store import frame_count, frames_bytes, FrameStore
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest


def test_frames_count_and_bytes():
    assert frame_count(2.0, 5e-4, 1) == 4001
    assert frame_count(2.0, 5e-4, 4) == 1001
    assert frame_count(2.0, 5e-4, 3) == 1334          # 0, 3, ..., 3999 steps
    assert frames_bytes(4001, 100) == 4001 * (100 * 3 * 8 + 8)


@pytest.mark.parametrize('in_memory_bytes', [10**9, 0])
def test_a_store_keeps_what_it_is_given_and_grows_past_its_capacity(in_memory_bytes, tmp_path):
    store = FrameStore(3, 5, tmp_path, in_memory_bytes=in_memory_bytes)
    assert store.on_disk == (in_memory_bytes == 0)
    frames = np.random.default_rng(0).normal(size=(8, 5, 3))
    for k, frame in enumerate(frames):
        store.append(0.1 * k, frame)
    np.testing.assert_array_equal(store.positions, frames)
    np.testing.assert_array_equal(store.times, 0.1 * np.arange(8))
    assert store.on_disk == (in_memory_bytes == 0)
    assert os.listdir(tmp_path) == []                     # its file has no name left behind
    store.clear()
    store.append(1.0, frames[3])
    np.testing.assert_array_equal(store.positions, frames[3:4])


def _sheet(method='modal'):
    return build_simulation(load_scene('sheet_10x10'), SimulationConfig(method=method))


def test_a_run_kept_in_a_file_writes_what_one_kept_in_memory_does(tmp_path, monkeypatch):
    kept = run.record(_sheet(), 0.2, frame_every=2)
    assert not isinstance(kept.positions, np.memmap)
    kept.save_npz(tmp_path / 'memory.npz')
    monkeypatch.setattr(frame_store, 'IN_MEMORY_BYTES', 0)
    monkeypatch.setattr(run, 'IN_MEMORY_BYTES', 0)
    filed = run.record(_sheet(), 0.2, frame_every=2, frames_dir=tmp_path)
    assert isinstance(filed.positions, np.memmap)
    filed.save_npz(tmp_path / 'file.npz')
    a, b = np.load(tmp_path / 'memory.npz'), np.load(tmp_path / 'file.npz')
    assert sorted(a.files) == sorted(b.files)
    assert a['positions'].shape == (201, 100, 3)
    for key in a.files:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)
    assert sorted(os.listdir(tmp_path)) == ['file.npz', 'memory.npz']   # no frames file left


def _traced(work):
    """Return what ``work()`` returns and the most memory it held at once beyond the start."""
    tracemalloc.start()
    try:
        start, _ = tracemalloc.get_traced_memory()
        result = work()
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    return result, peak - start


def test_a_run_kept_in_memory_holds_one_copy_of_its_frames():
    """A list of frames stacked at the end held two (and a cast before writing, three)."""
    sim = _sheet('full')
    kept, peak = _traced(lambda: run.record(sim, 1.0))      # 2,001 frames, 4.8 MB
    assert kept.positions.nbytes == 2001 * 100 * 3 * 8
    assert peak < 1.3 * kept.positions.nbytes, (peak, kept.positions.nbytes)


def test_a_run_kept_in_a_file_is_recorded_and_written_in_little_memory(tmp_path, monkeypatch):
    """sheet_32x32 over 4,000 steps: 98 MB of frames, never in memory at once."""
    monkeypatch.setattr(frame_store, 'IN_MEMORY_BYTES', 32 * 2**20)
    monkeypatch.setattr(run, 'IN_MEMORY_BYTES', 32 * 2**20)
    sim = build_simulation(load_scene('sheet_32x32'), SimulationConfig(method='full'))
    kept, recording = _traced(lambda: run.record(sim, 4000 * sim.dt, frames_dir=tmp_path))
    frames = kept.positions.nbytes
    assert isinstance(kept.positions, np.memmap) and frames == 4001 * 1024 * 3 * 8
    _, writing = _traced(lambda: kept.save_npz(tmp_path / 'run.npz'))
    print(f'frames {frames / 1e6:.1f} MB; at most {recording / 1e6:.1f} MB held recording, '
          f'{writing / 1e6:.1f} MB writing')
    assert recording < 0.1 * frames and writing < 0.5 * frames, (recording, writing, frames)
    with np.load(tmp_path / 'run.npz') as saved:
        np.testing.assert_array_equal(saved['positions'][-1], sim.positions())

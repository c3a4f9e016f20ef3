"""What several tests share: where things are, scenes made for a test, a disk that fills."""
from __future__ import annotations

import builtins
import copy
import errno
import io
import math
import os
from pathlib import Path
import time

from modal_spring_ros.bench.costs import meshes
from modal_spring_ros.bench.costs.meshes import write_obj  # noqa: F401 (the tests' too)
from modal_spring_ros.scenes.files.writing import scene_to_dict
from modal_spring_ros.scenes.resources import load_scene
from modal_spring_ros.scenes.schema import scene_from_dict
import numpy as np

#: the repository (a source checkout)
REPO = Path(__file__).resolve().parents[1]
#: the reference bags shipped with the package
BAGS = REPO / 'bags'
#: the real rosbag2 recordings beside the repository (CI has them)
REAL_BAGS = Path(os.environ.get('MODAL_SPRING_REAL_BAGS', REPO.parent / 'shared' / 'real_bags'))

#: ROS packages made unimportable (as in a venv without the ROS wheels)
HIDDEN = ('rclpy', 'rosidl', 'rpyutils', 'ament_index_python', 'builtin_interfaces',
          'std_msgs', 'sensor_msgs', 'geometry_msgs', 'std_srvs', 'rcl_interfaces',
          'diagnostic_msgs', 'visualization_msgs', 'rosgraph_msgs', 'tf2_msgs', 'rosbags',
          'simulation_interfaces')

#: Python that hides them from what runs after it (``python -c HIDE_ROS + code``)
HIDE_ROS = f"""
import importlib.abc, sys
class Hidden(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if name.split('.')[0].startswith({HIDDEN!r}):
            raise ModuleNotFoundError(f'No module named {{name!r}} (hidden)', name=name)
sys.meta_path.insert(0, Hidden())
"""


def variant(name: str, **changes):
    """Return a built-in scene's full definition with top-level fields replaced, validated."""
    data = copy.deepcopy(scene_to_dict(load_scene(name)))
    data.update(changes)
    return scene_from_dict(data, source=f'{name} variant')


def sheet_on_a_table(*colliders: dict):
    """
    Return sheet_10x10 pressed by its clamp onto a table 1.5 cm under its bottom row.

    Its clamp moves up and down (2.5 cm at 1 Hz): the bottom row touches from 0.6 s;
    ``colliders``: more colliders beside the table.
    """
    return variant('sheet_10x10', anchor_motion=[
        {'axis': 'z', 'amplitude': 0.025, 'frequency_hz': 1.0, 'ramp_s': 0.2}], contact={
            'friction': 0.3,
            'colliders': [{'shape': 'plane', 'point': [0, 0, -0.915], 'normal': [0, 0, 1]},
                          *colliders]})


def head_start_gap(sim, head) -> float:
    """
    Return how far ``head`` is from ``sim``'s run stepped from rest to its time.

    The largest difference in displacement, relative to the head's largest (1: nothing moved).
    """
    again = sim.with_dt(sim.dt)
    again.step(round(head.time / sim.dt))
    assert abs(again.time - head.time) <= 1e-9 * max(head.time, 1.0)
    size = float(np.abs(head.displacement()).max())
    gap = float(np.abs(again.displacement() - head.displacement()).max())
    return gap / size if size > 0 else 1.0


def hanging_sheet(count: int) -> dict:
    """Return ``sheet_316x316``'s definition with ``count`` x ``count`` particles (0.9 m, 1 kg)."""
    return {
        'name': f'sheet_{count}x{count}', 'dimension': 2, 'plane': 'xz',
        'particles': {'lattice': {'counts': [count, count], 'spacing': 0.9 / (count - 1),
                                  'origin': [0.0, 0.0, -0.9]}, 'mass': 1.0 / count ** 2},
        'springs': {'connect': ['edges', 'diagonals'], 'stiffness': 1000.0},
        'fixed': {'face': '+z'}, 'gravity': [0.0, 0.0, -9.81],
        'damping': {'rayleigh': {'alpha': 1.2, 'beta': 0.0}},
        'anchor_motion': [{'axis': 'x', 'amplitude': 0.02, 'frequency_hz': 0.7, 'ramp_s': 1.0}],
    }


def cloth_mesh(count: int, size: float = 0.5, jitter: float = 0.25, seed: int = 1):
    """Return a square cloth in the x-z plane (top edge at z = 0), irregularly triangulated."""
    return meshes.cloth_mesh(count, size, seed, top=0.0, jitter=jitter)


def oscillator(k: float = 400.0, m: float = 0.25, gravity: float = 0.0):
    """One free mass on one spring (1D): omega = sqrt(k / m)."""
    return scene_from_dict({
        'name': 'oscillator', 'dimension': 1, 'axis': 'x',
        'particles': {'positions': [[0.0, 0.0], [1.0, 0.0]], 'mass': [1.0, m]},
        'springs': {'pairs': [[0, 1]], 'stiffness': k},
        'fixed': {'indices': [0]}, 'gravity': [gravity, 0.0, 0.0],
    })


def power_above(sim, cutoff_hz: float, steps: int, below_hz: float = np.inf) -> float:
    """
    Share of the displacement power above ``cutoff_hz`` (and below ``below_hz``).

    Share of the displacement power above ``cutoff_hz`` (and below ``below_hz``) over the next
    ``steps`` steps.
    """
    frames = np.empty((steps, sim.model.n_free_dof))
    for k in range(steps):
        sim.step()
        frames[k] = sim.displacement()
    frames -= frames.mean(axis=0)
    spectrum = np.abs(np.fft.rfft(frames * np.hanning(steps)[:, None], axis=0)) ** 2
    power = spectrum.sum(axis=1)
    f = np.fft.rfftfreq(steps, sim.dt)
    return float(power[(f > cutoff_hz) & (f < below_hz)].sum() / power.sum())


def max_step_motion(sim, steps: int) -> float:
    """Return the most any particle moves in one step over the next ``steps`` steps, m."""
    worst, prev = 0.0, sim.positions()
    for _ in range(steps):
        sim.step()
        now = sim.positions()
        worst = max(worst, float(np.linalg.norm(now - prev, axis=1).max()))
        prev = now
    return worst


class FullAfter(io.RawIOBase):
    """A file that takes ``budget`` bytes, then fails every write as a full disk does."""

    def __init__(self, fh, budget: int):
        self._fh, self._budget = fh, budget

    def writable(self) -> bool:
        return True

    def write(self, data) -> int:
        data = bytes(data)
        room = self._budget - self._fh.tell()
        if len(data) > room:
            self._fh.write(data[:max(room, 0)])
            raise OSError(errno.ENOSPC, 'No space left on device')
        return self._fh.write(data)

    def tell(self) -> int:
        return self._fh.tell()

    def flush(self) -> None:
        if not self._fh.closed:
            self._fh.flush()

    def close(self) -> None:
        super().close()
        self._fh.close()


def fill_disk_after(monkeypatch, budget: int) -> None:
    """Make bag (.mcap) and run (.npz) files opened from now on fill up after ``budget`` bytes."""
    real_open = builtins.open

    def full_open(path, mode='r', *args, **kwargs):
        fh = real_open(path, mode, *args, **kwargs)
        if 'w' in mode and 'b' in mode and str(path).endswith(('.mcap', '.npz')):
            return FullAfter(fh, budget)
        return fh
    monkeypatch.setattr(builtins, 'open', full_open)


def random_band(rng: np.random.Generator, top_hz: float) -> dict:
    """
    Return the fields of a random equaliser band over 0..``top_hz`` (``FilterBand(**fields)``).

    Any kind, edge order 0-8, up to two gain terms of -12..+18 dB (ranges, peaks, shelves), a
    damping range now and then, acting on the output or on the loads: what a user turning the
    knobs sends. Not every band is valid (a band may keep no mode): the caller sees it refused.
    """
    kind = str(rng.choice(['allpass', 'lowpass', 'highpass', 'bandpass', 'bandstop']))
    a, b = sorted(rng.uniform(0.0, top_hz, 2))
    gains = []
    for _ in range(int(rng.integers(0, 3))):
        db = float(rng.choice([-12.0, -6.0, 6.0, 12.0, 18.0]))
        shape = int(rng.integers(0, 3))
        if shape == 0:
            lo, hi = sorted(rng.uniform(0.0, top_hz, 2))
            gains.append(f'{lo:.2f}:{hi + 0.1:.2f}:{db:g}')
        elif shape == 1:
            center, width = rng.uniform(1.0, top_hz), rng.uniform(0.5, 10.0)
            gains.append(f'peak:{center:.2f}:{width:.2f}:{db:g}')
        else:
            side = rng.choice(['low_shelf', 'high_shelf'])
            gains.append(f'{side}:{rng.uniform(1.0, top_hz):.2f}:{db:g}')
    damping = []
    if rng.random() < 0.4:
        lo, hi = sorted(rng.uniform(0.0, top_hz, 2))
        damping.append(f'{lo:.2f}:{hi:.2f}:{rng.uniform(0.0, 1.0):.2f}')
    return {'kind': kind,
            'low': 0.0 if kind in ('allpass', 'lowpass') else round(float(a), 2),
            'high': math.inf if kind in ('allpass', 'highpass') else round(float(b) + 0.5, 2),
            'order': int(rng.integers(0, 9)), 'gains': tuple(gains),
            'acts_on': str(rng.choice(['output', 'load'])), 'damping': tuple(damping)}


def stat_fields(pid: int | str) -> list[str]:
    """Return process ``pid``'s ``/proc`` stat fields from its state on (Linux; OSError: gone)."""
    with open(f'/proc/{pid}/stat') as stat:
        return stat.read().rsplit(')', 1)[1].split()


def niceness(pid: int) -> int:
    """Return the niceness of process ``pid`` (from its ``/proc`` stat, Linux)."""
    return int(stat_fields(pid)[16])


def spawned_niceness(pgid: int) -> list[int]:
    """Return the niceness of each process in group ``pgid`` that ``multiprocessing`` spawned."""
    found = []
    for entry in os.listdir('/proc'):
        try:
            group = stat_fields(entry)[2]
            spawned = b'spawn_main' in Path(f'/proc/{entry}/cmdline').read_bytes()
            if group == str(pgid) and spawned:
                found.append(niceness(int(entry)))
        except (OSError, IndexError, ValueError):
            continue
    return found


def process_group(pgid: int, wait_s: float = 0.5) -> list[str]:
    """Return the processes still in group ``pgid`` after up to ``wait_s`` (pid and name)."""
    end = time.monotonic() + wait_s
    while True:
        left = []
        for entry in os.listdir('/proc'):
            try:
                fields = stat_fields(entry)
                name = open(f'/proc/{entry}/comm').read().strip()
            except (OSError, IndexError, ValueError):
                continue
            if fields[2] == str(pgid) and fields[0] != 'Z':
                left.append(f'{entry} {name}')
        if not left or time.monotonic() > end:
            return left
        time.sleep(0.05)

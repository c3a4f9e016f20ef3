"""
Compare two runs of the same scene frame by frame (``.npz`` runs or bags, in any mix).

Frames are aligned by their time (simulation time: a bag's recorded ``sim_time`` where the
node stamped with its clock, else the stamps; ``bags/files/run_loading.py``). Per frame: RMS and
largest position difference, relative L2 error of A against B's displacement, and, where the
scene is known, each run's mechanical energy (springs, gravity, and kinetic from finite
differences of positions). Per run: the displacement spectrum and, when the run says which
modes it kept, that frequency band.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path
import zipfile

from modal_spring_ros.core.laws import scene_law
from modal_spring_ros.core.model.scene import Scene
from modal_spring_ros.runs.run_memory import (check_fits, npz_positions, positions_budget,
                                              RunTooLarge)
from modal_spring_ros.scenes.files.scene_archive import recorded_scene
import numpy as np


class RunError(ValueError):
    """A run that cannot be read."""


class ComparisonError(ValueError):
    """Two runs that cannot be compared (different scenes, no common frames)."""


@dataclasses.dataclass
class RunData:
    name: str
    t: np.ndarray              # (F,) s
    positions: np.ndarray      # (F, n, 3)
    scene: Scene | None
    band_hz: tuple[float, float] | None  # frequency span of the kept modes, when known
    label: str = ''

    @property
    def rest(self) -> np.ndarray:
        return self.scene.rest_positions if self.scene is not None else self.positions[0]


def load_npz_run(path: str | Path, budget: int | None = None) -> RunData:
    """
    Return a ``modal_spring_sim`` ``.npz`` run as arrays. Raises RunError.

    Its positions' size is read from their header first, and a run beyond ``budget`` bytes
    (:func:`~modal_spring_ros.runs.run_memory.positions_budget` by default) is refused unread.
    """
    path = Path(path)
    try:
        declared = npz_positions(path)
        shape = declared.shape
        if len(shape) != 3 or shape[2] != 3:
            raise ValueError(f"'positions' has the shape {shape}, not (frames, particles, 3)")
        check_fits(declared.nbytes, str(path), shape[0], shape[1],
                   positions_budget() if budget is None else budget)
        data = np.load(path, allow_pickle=False)
        scene = recorded_scene(
            data['scene_archive'].tobytes() if 'scene_archive' in data else None,
            str(data['scene_yaml']) if 'scene_yaml' in data else None, f'{path} (scene)')
        band = None
        if data['frequencies_hz'].size and data['kept_modes'].size:
            kept = data['frequencies_hz'][data['kept_modes']]
            band = (float(kept.min()), float(kept.max()))
        run = RunData(path.name, data['t'], data['positions'], scene, band,
                      f"{data['method']} {data['band']}")
    except RunTooLarge as exc:
        raise RunError(str(exc)) from None
    except (OSError, KeyError, ValueError, zipfile.BadZipFile) as exc:
        raise RunError(f'{path}: not a modal_spring_sim .npz run: {exc}') from None
    if not np.isfinite(run.positions).all():
        raise RunError(f'{path}: damaged: its positions hold non-finite values')
    return run


def check_same_scene(a: RunData, b: RunData) -> None:
    if a.positions.shape[1] != b.positions.shape[1]:
        raise ComparisonError(f'different scenes: {a.name} has {a.positions.shape[1]} '
                              f'particles, {b.name} has {b.positions.shape[1]}')
    if a.scene is not None and b.scene is not None and not np.allclose(
            a.scene.rest_positions, b.scene.rest_positions, atol=1e-9):
        raise ComparisonError(f'different scenes: {a.name} and {b.name} have other rest '
                              'shapes')


def align(a: RunData, b: RunData) -> tuple[np.ndarray, np.ndarray]:
    """Return the indices of the frames of A and B with equal times (to the microsecond)."""
    ka = np.round(a.t * 1e6).astype(np.int64)
    kb = np.round(b.t * 1e6).astype(np.int64)
    common, ia, ib = np.intersect1d(ka, kb, return_indices=True)
    if common.size == 0:
        raise ComparisonError(f'{a.name} and {b.name} share no frame times')
    return ia, ib


def energy(run: RunData) -> np.ndarray | None:
    """Mechanical energy per frame (springs, bending, gravity, kinetic by central differences)."""
    if run.scene is None or run.t.size < 3:
        return None
    s = run.scene
    x = run.positions
    i, j = s.springs[:, 0], s.springs[:, 1]
    length = np.linalg.norm(x[:, j] - x[:, i], axis=2)
    spring = scene_law(s).energy(length).sum(axis=1)
    if s.bending is not None:   # 1/2 sum_h |sum_i w_hi x_hi|^2, every frame at once
        bent = np.einsum('hi,fhid->fhd', s.bending.weights, x[:, s.bending.hinges])
        spring = spring + 0.5 * np.einsum('fhd,fhd->f', bent, bent)
    free = ~s.fixed
    gravity = -(x[:, free] @ s.gravity * s.mass[free]).sum(axis=1)
    v = np.gradient(x[:, free], run.t, axis=0)
    kinetic = 0.5 * (s.mass[free][None, :] * (v ** 2).sum(axis=2)).sum(axis=1)
    return spring + gravity + kinetic


def deformation(run: RunData) -> np.ndarray:
    """
    Return the (F, n, 3) displacement from rest relative to the moving base.

    The moving base is the fixed particles' common offset: what is left is what the filter
    shapes. Plain displacement when the scene is unknown.
    """
    u = run.positions - run.rest
    if run.scene is not None:
        u = u - u[:, run.scene.fixed].mean(axis=1, keepdims=True)
    return u


def spectrum(run: RunData) -> tuple[np.ndarray, np.ndarray]:
    """Mean-square deformation per frequency (Hann window), over all particles."""
    u = deformation(run).reshape(run.t.size, -1)
    u = u - u.mean(axis=0)
    dt = float(np.median(np.diff(run.t))) if run.t.size > 1 else 1.0
    w = np.hanning(run.t.size)
    power = (np.abs(np.fft.rfft(u * w[:, None], axis=0)) ** 2).sum(axis=1) / (w.sum() ** 2)
    return np.fft.rfftfreq(run.t.size, dt), power


def compare(a: RunData, b: RunData) -> dict:
    check_same_scene(a, b)
    ia, ib = align(a, b)
    xa, xb = a.positions[ia], b.positions[ib]
    diff = np.linalg.norm(xa - xb, axis=2)                         # (F, n)
    rms = np.sqrt((diff ** 2).mean(axis=1))
    worst = diff.max(axis=1)
    ref = np.linalg.norm((xb - b.rest).reshape(len(ib), -1), axis=1)
    rel = np.linalg.norm((xa - xb).reshape(len(ia), -1), axis=1) / np.maximum(ref, 1e-300)
    ea, eb = energy(a), energy(b)
    frames = [{'t': float(a.t[p]), 'rms_m': float(r), 'max_m': float(m), 'rel_l2': float(e),
               **({'energy_a_J': float(ea[p])} if ea is not None else {}),
               **({'energy_b_J': float(eb[q])} if eb is not None else {})}
              for p, q, r, m, e in zip(ia, ib, rms, worst, rel)]
    fa, pa = spectrum(a)
    fb, pb = spectrum(b)
    return {
        'a': {'name': a.name, 'label': a.label, 'frames': int(a.t.size), 'band_hz': a.band_hz},
        'b': {'name': b.name, 'label': b.label, 'frames': int(b.t.size), 'band_hz': b.band_hz},
        'common_frames': int(len(ia)),
        'rms_m': float(np.sqrt((rms ** 2).mean())),
        'max_m': float(worst.max()),
        'rel_l2_mean': float(rel[1:].mean()) if len(rel) > 1 else float(rel.mean()),
        'rel_l2_max': float(rel[1:].max()) if len(rel) > 1 else float(rel.max()),
        'per_frame': frames,
        'spectrum_a': {'hz': fa.tolist(), 'power': pa.tolist()},
        'spectrum_b': {'hz': fb.tolist(), 'power': pb.tolist()},
    }


def plot(result: dict, path: str | Path) -> None:
    # deferred on purpose: matplotlib takes ~0.5 s to import and only --plot needs it
    from matplotlib.figure import Figure  # no pyplot: no display, no global figure state
    fig = Figure(figsize=(8, 7))
    top, bottom = fig.subplots(2, 1)
    t = [f['t'] for f in result['per_frame']]
    top.plot(t, [f['rel_l2'] for f in result['per_frame']], label='relative L2 error')
    top.plot(t, [f['max_m'] for f in result['per_frame']], label='largest difference (m)')
    top.set_yscale('log')
    top.set_xlabel('time (s)')
    top.set_title(f"{result['a']['name']} against {result['b']['name']}")
    top.legend()
    for key, side in (('spectrum_a', 'a'), ('spectrum_b', 'b')):
        spec = result[key]
        bottom.semilogy(spec['hz'][1:], np.maximum(spec['power'][1:], 1e-30),
                        label=f"{result[side]['name']} {result[side]['label']}")
        band = result[side]['band_hz']
        if band:
            bottom.axvspan(band[0], band[1], alpha=0.15, color='C0' if side == 'a' else 'C1',
                           label=f"kept modes of {result[side]['name']}")
    bottom.set_xlabel('frequency (Hz)')
    bottom.set_ylabel('deformation power (m^2), relative to the base')
    bottom.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)

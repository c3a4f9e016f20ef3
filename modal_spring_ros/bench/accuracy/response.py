"""
The filter's response measured: requested against measured gain and damping, mode by mode.

On ``sheet_10x10`` with a still clamp and no gravity (the motion is the response to the drive
alone), rest modes only:

- ``output``: a broadband start (every mode given the same modal velocity) run with an
  equaliser acting on the output; each mode's gain is the RMS of its coordinate in the
  streamed positions over its RMS in the simulated motion (``phi_i^T M u``), exact to
  round-off by construction.
- ``load``: a multisine base drive (1-150 Hz, in x and z) run all-pass and with the same
  equaliser acting on the loads; each mode's gain is the RMS of its coordinate over the all-pass
  run's. The motion is small (linear), so it is the requested gain up to the springs'
  nonlinearity (modes the drive hardly reaches are left out).
- ``damping``: the broadband start decaying freely with damping ranges; each mode's ratio is
  its decay rate over its circular frequency (a line through the logarithm of its peaks).

Results: ``response.json``, ``response.csv`` and ``response.png`` (requested against measured,
per mode).
"""
from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Callable

from modal_spring_ros.bench.charts import subplots
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.filter_response import damping_ratios
from modal_spring_ros.scenes.files.writing import scene_to_dict
from modal_spring_ros.scenes.resources import load_scene
from modal_spring_ros.scenes.schema import scene_from_dict
import numpy as np

#: the equaliser measured: rounded band-pass edges, a peak and a shelf
EQUALISER = {'kind': 'bandpass', 'low': 8.0, 'high': 60.0, 'order': 2,
             'gains': ('peak:20:6:9', 'high_shelf:80:-6')}
#: the damping ranges measured
DAMPING = ('0:20:0.01', '20:50:0.04', '50:1000:0.08')
DT_S, DURATION_S, QUICK_DURATION_S = 2e-4, 2.0, 1.0
#: a decay is measured down to this share of its start
DECAY_FLOOR = 1e-2
#: every mode's modal velocity at the broadband start (small: the linear regime)
START_VELOCITY = 0.005
#: modes whose all-pass motion is below this share of the largest are not measured (load)
REACHED = 1e-3


def still_scene(drive: bool):
    """Return sheet_10x10 with no gravity, and the clamp still or driven by a multisine."""
    data = scene_to_dict(load_scene('sheet_10x10'))
    data['gravity'] = [0.0, 0.0, 0.0]
    data['anchor_motion'] = [] if not drive else [
        {'axis': axis, 'amplitude': 2e-6 / (1 + f / 20.0), 'frequency_hz': f,
         'phase': 0.7 * k, 'ramp_s': 0.0}
        for k, f in enumerate(np.geomspace(1.0, 150.0, 24).round(3).tolist())
        for axis in ('x', 'z')]
    return scene_from_dict(data, source='response benchmark')


def _run(scene, band: FilterBand, duration: float, start: bool, sample_every: int = 2):
    sim = build_simulation(scene, SimulationConfig(band=band, basis='rest', dt=DT_S))
    modes = sim.kept_modes
    phi, m = sim.basis.vectors[:, modes], sim.model.mass_dof
    if start:   # every mode the same modal velocity: a broadband start
        sim.set_state(np.zeros(phi.shape[0]), phi @ np.full(modes.size, START_VELOCITY))
    steps = int(round(duration / DT_S))
    t, shown, physical = [], [], []
    for _ in range(steps // sample_every):
        sim.step(sample_every)
        t.append(sim.time)
        shown.append(phi.T @ (m * sim.shown_displacement()))
        physical.append(phi.T @ (m * sim.displacement()))
    return sim, modes, np.array(t), np.array(shown), np.array(physical)


def _rms(x: np.ndarray) -> np.ndarray:
    return np.sqrt(np.mean(x * x, axis=0))


def _decay_ratio(t: np.ndarray, q: np.ndarray, omega: float) -> float:
    """
    Return the damping ratio of a decaying coordinate: its peaks' log-decay over ``omega``.

    Only peaks above :data:`DECAY_FLOOR` of the first count (below, what other modes pass on
    through the springs' nonlinearity is seen, not the decay).
    """
    top = np.abs(q).max()
    peaks = np.flatnonzero((q[1:-1] > q[:-2]) & (q[1:-1] >= q[2:])
                           & (q[1:-1] > DECAY_FLOOR * top)) + 1
    if peaks.size < 3:
        return math.nan
    return float(-np.polyfit(t[peaks], np.log(q[peaks]), 1)[0] / omega)


def run(quick: bool, progress: Callable[[str], None]) -> dict:
    duration = QUICK_DURATION_S if quick else DURATION_S
    rows = []
    still = still_scene(drive=False)
    progress('output gains: a broadband start, shown against simulated')
    band = FilterBand(**EQUALISER).validate()
    sim, modes, _, shown, physical = _run(still, band, duration, start=True)
    f = sim.basis.frequencies_hz[modes]
    measured = _rms(shown) / _rms(physical)
    rows += [{'case': 'output', 'mode': int(i), 'hz': float(fi), 'requested': float(g),
              'measured': float(mg)} for i, fi, g, mg in zip(modes, f, band.gain(f), measured)]
    progress('load gains: a multisine drive, against the all-pass run')
    driven = still_scene(drive=True)
    _, all_modes, _, _, plain = _run(driven, FilterBand(), duration, start=False)
    load = FilterBand(**EQUALISER, acts_on='load').validate()
    sim, modes, _, _, loaded = _run(driven, load, duration, start=False)
    reference = _rms(plain)[np.searchsorted(all_modes, modes)]
    reached = reference > REACHED * reference.max()
    f = sim.basis.frequencies_hz[modes]
    measured = _rms(loaded) / np.where(reached, reference, 1.0)
    rows += [{'case': 'load', 'mode': int(i), 'hz': float(fi), 'requested': float(g),
              'measured': float(mg)}
             for i, fi, g, mg, ok in zip(modes, f, load.gain(f), measured, reached) if ok]
    progress('damping ranges: a broadband start decaying freely')
    damped = FilterBand(damping=DAMPING).validate()
    sim, modes, t, _, q = _run(still, damped, duration, start=True, sample_every=1)
    f = sim.basis.frequencies_hz[modes]
    requested = damping_ratios(DAMPING, f)
    for k, (i, fi) in enumerate(zip(modes, f)):
        ratio = _decay_ratio(t, q[:, k], 2 * math.pi * fi)
        if math.isfinite(ratio):
            rows.append({'case': 'damping', 'mode': int(i), 'hz': float(fi),
                         'requested': float(requested[k]), 'measured': ratio})
    return {'rows': rows, 'summary': _summary(rows)}


def _summary(rows: list[dict]) -> list[dict]:
    out = []
    for case in ('output', 'load', 'damping'):
        mine = [r for r in rows if r['case'] == case]
        rel = [abs(r['measured'] / r['requested'] - 1.0) for r in mine if r['requested'] > 0]
        out.append({'case': case, 'modes': len(mine),
                    'worst_relative_error': max(rel, default=0.0),
                    'median_relative_error': float(np.median(rel)) if rel else 0.0})
    return out


def table(results: dict) -> str:
    lines = [f"{'case':>8s} {'modes':>5s} {'median error':>12s} {'worst error':>11s}"]
    for s in results['summary']:
        lines.append(f"{s['case']:>8s} {s['modes']:5d} {s['median_relative_error']:12.2e} "
                     f"{s['worst_relative_error']:11.2e}")
    return '\n'.join(lines)


def write_outputs(results: dict, out: Path, progress) -> None:
    rows = results['rows']
    with open(out / 'response.csv', 'w', newline='') as f:
        writer = csv.DictWriter(f, fieldnames=['case', 'mode', 'hz', 'requested', 'measured'])
        writer.writeheader()
        writer.writerows(rows)
    progress(f"wrote {out / 'response.csv'} and {chart(rows, out / 'response.png')}")


def chart(rows: list[dict], path: Path) -> Path:
    """Draw the requested and measured gain (dB) and damping ratio of each mode."""
    fig, (left, right) = subplots(1, 2, figsize=(11, 4.5))
    curve = np.geomspace(1.0, 200.0, 800)
    left.semilogx(curve, 20 * np.log10(FilterBand(**EQUALISER).gain(curve)), color='0.6',
                  lw=1, label='requested')
    for case, marker in (('output', 'o'), ('load', 'x')):
        mine = [r for r in rows if r['case'] == case]
        db = [20 * math.log10(max(r['measured'], 1e-6)) for r in mine]
        left.semilogx([r['hz'] for r in mine], db, marker, ms=4, label=f'measured, {case} gains')
    left.set_ylim(-70, 15)
    left.set_xlabel('mode frequency, Hz')
    left.set_ylabel('gain, dB')
    left.set_title('equaliser: rounded band-pass 8-60 Hz, +9 dB peak, -6 dB shelf', fontsize=9)
    left.legend(fontsize=8)
    damping = [r for r in rows if r['case'] == 'damping']
    right.semilogx([r['hz'] for r in damping], [r['requested'] for r in damping], '-',
                   color='0.6', label='requested')
    right.semilogx([r['hz'] for r in damping], [r['measured'] for r in damping], 'o', ms=4,
                   label='measured (decay)')
    right.set_xlabel('mode frequency, Hz')
    right.set_ylabel('modal damping ratio')
    right.set_title('damping ranges', fontsize=9)
    right.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path

"""
The README's figures over the runs users make: cost at 1 % error over 1 s and 5 s of simulation.

On one scene, the run a user starts (``modal_spring_sim --duration T``) is checked over ``T``
for each duration of :data:`DURATIONS_S`, against the full run converged in its step to a tenth
of the tolerance (:func:`~modal_spring_ros.bench.accuracy.promise.full_run_check`):
- ``full``: the full explicit run at the longest step that meets the tolerance over the longest
  duration (the baseline each ratio is taken against);
- ``auto``: ``--auto --tolerance 0.01 --duration T``, planned for that run (it chooses the modes,
  the step and the spring forces: sampled on scenes of 20,000 springs and more);
- ``N modes, sampled springs``: the band of the lowest ``N`` rest modes with sampled springs at a
  step and its halves (the cheapest of them that meets the tolerance over ``T`` is the figure).
The error of each is the relative L2 error of the displacement over the whole run (the promise
suite's measure); the cost is CPU seconds per simulated second over the longest duration, all
in one process with one BLAS thread. Results: ``headline.json`` and ``headline.csv``.
"""
from __future__ import annotations

import csv
import dataclasses
import math
from pathlib import Path
from typing import Callable

from modal_spring_ros.bench.accuracy.promise import converged_reference, cpu_per_second
from modal_spring_ros.core.auto.measured_error import on_samples, trajectory, trajectory_error
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.threads import stepping_threads
from modal_spring_ros.runs.sample_cache import sample_cache
from modal_spring_ros.scenes.resources import load_scene

SCENE, QUICK_SCENE = 'sheet_100x100', 'sheet_32x32'
DURATIONS_S, QUICK_DURATIONS_S = (1.0, 5.0), (0.5, 1.0)
TOLERANCE = 0.01
SAMPLE_S = 0.01
#: the band of the sampled runs, and the steps they are tried at (s)
SAMPLED_MODES = 32
SAMPLED_STEPS_S = (SAMPLE_S / 6, SAMPLE_S / 12, SAMPLE_S / 24)


@dataclasses.dataclass
class Row:
    """One run checked over one duration."""

    run: str
    duration_s: float
    coordinates: int
    dt: float
    error: float
    cpu_per_s: float
    ratio: float = math.nan        # the full baseline's CPU per simulated second over this one
    forces: str = ''               # how the spring forces were evaluated


def _window_error(run, reference, samples: int) -> float:
    """Return the error over the first ``samples`` samples (inf where the run diverged)."""
    if run is None:
        return math.inf
    return trajectory_error(run[:samples], reference[:samples])


@stepping_threads()         # one BLAS thread, as the node and modal_spring_sim step
def measure(scene_name: str, durations: tuple[float, ...], progress: Callable[[str], None]
            ) -> dict:
    """Return the rows of :data:`Row` for ``scene_name`` over each of ``durations``."""
    scene = load_scene(scene_name)
    longest = max(durations)
    samples = int(round(longest / SAMPLE_S))
    reference, full, _ = converged_reference(scene, SAMPLE_S, samples, TOLERANCE, progress)
    full_cpu = cpu_per_second(full, longest)
    full_run = trajectory(full, SAMPLE_S, samples)
    rows = []

    def add(name: str, sim, run, duration: float, cpu: float) -> None:
        rows.append(Row(name, duration, int(sim.coordinates), float(sim.dt),
                        _window_error(run, reference, int(round(duration / SAMPLE_S))), cpu,
                        full_cpu / cpu if cpu > 0 else math.nan,
                        sim.force_report().description))

    for duration in durations:
        add('full', full, full_run, duration, full_cpu)
    for duration in durations:
        progress(f'{scene_name}: auto planned for {duration:g} s')
        # per simulated second: planned unbudgeted (its planning is not what is compared)
        config = SimulationConfig(auto=True, tolerance=TOLERANCE, horizon_s=duration,
                                  planning_share=None)
        sim = on_samples(build_simulation(scene, config, samples=sample_cache()), SAMPLE_S)
        add('auto', sim, trajectory(sim, SAMPLE_S, int(round(duration / SAMPLE_S))), duration,
            cpu_per_second(sim, longest))
    band = FilterBand('lowpass', 0, SAMPLED_MODES - 1, 'index')
    for dt in SAMPLED_STEPS_S:
        name = f'{SAMPLED_MODES} modes, sampled springs'
        progress(f'{scene_name}: {name} at dt {dt:.3g} s')
        config = SimulationConfig(band=band, basis='rest', forces='sampled', dt=dt)
        sim = on_samples(build_simulation(scene, config, samples=sample_cache()), SAMPLE_S)
        run, cpu = trajectory(sim, SAMPLE_S, samples), cpu_per_second(sim, longest)
        for duration in durations:
            add(name, sim, run, duration, cpu)
    return {'scene': scene_name, 'particles': scene.n_particles, 'tolerance': TOLERANCE,
            'durations_s': list(durations), 'full_dt': float(full.dt),
            'rows': [dataclasses.asdict(r) for r in rows]}


def figures(results: dict) -> list[dict]:
    """Return the cheapest run of each kind within the tolerance, per duration (x full)."""
    out = []
    for duration in results['durations_s']:
        for kind in ('auto', f'{SAMPLED_MODES} modes, sampled springs'):
            within = [r for r in results['rows'] if r['run'] == kind
                      and r['duration_s'] == duration and r['error'] <= results['tolerance']]
            best = min(within, key=lambda r: r['cpu_per_s'], default=None)
            out.append({'duration_s': duration, 'run': kind,
                        'ratio': best['ratio'] if best else None,
                        'error': best['error'] if best else None,
                        'dt': best['dt'] if best else None})
    return out


def run(quick: bool, progress: Callable[[str], None]) -> dict:
    results = measure(QUICK_SCENE if quick else SCENE,
                      QUICK_DURATIONS_S if quick else DURATIONS_S, progress)
    results['figures'] = figures(results)
    return results


def table(results: dict) -> str:
    lines = [f"{results['scene']} ({results['particles']} particles), tolerance "
             f"{results['tolerance']:.0%}; the full run at dt {results['full_dt']:.3g} s",
             f"{'run':<28} {'T (s)':>6} {'coords':>6} {'dt (s)':>9} {'error':>8} "
             f"{'CPU s/s':>9} {'x full':>7}"]
    for r in results['rows']:
        lines.append(f"{r['run']:<28} {r['duration_s']:>6g} {r['coordinates']:>6} "
                     f"{r['dt']:>9.3g} {r['error']:>8.2%} {r['cpu_per_s']:>9.4f} "
                     f"{r['ratio']:>7.1f}")
    lines.append('cheapest within the tolerance (x cheaper than the full run):')
    for f in results['figures']:
        what = (f"{f['ratio']:.0f}x at {f['error']:.2%} (dt {f['dt']:.3g} s)"
                if f['ratio'] is not None else 'none within the tolerance')
        lines.append(f"  over {f['duration_s']:g} s, {f['run']}: {what}")
    return '\n'.join(lines)


def write_outputs(results: dict, out: Path, progress) -> None:
    path = out / 'headline.csv'
    with open(path, 'w', newline='') as fh:
        writer = csv.DictWriter(fh, fieldnames=[f.name for f in dataclasses.fields(Row)])
        writer.writeheader()
        writer.writerows(results['rows'])
    progress(f'wrote {path}')

"""
``modal.auto`` on the built-in scenes: the plan as predicted against the plan measured, one run.

Before ``modal.auto`` measured its plans it ran the plan its prediction gave. For each built-in
scene small enough for a converged full reference, and each tolerance ``T``, this suite builds both
in one process, one after the other: the predicted plan
(:func:`~modal_spring_ros.core.factory.predicted_simulation`, no pilot) and the plan the pilot
measured (or the full run it chose). Each is checked over the scene's run (at most
``MAX_DURATION_S``, the horizon auto is asked to hold its tolerance over) against the full run
converged in its step to a tenth of ``T``, and timed, CPU per simulated second, against the full
run at the longest step that meets ``T``
(:func:`~modal_spring_ros.bench.accuracy.promise.full_run_check`). Single-threaded BLAS, one scene
after another.

Results: ``auto.json`` and ``auto.csv`` (a row per scene and tolerance).
"""
from __future__ import annotations

import math
from pathlib import Path
import time
from typing import Callable

from modal_spring_ros.bench.accuracy.promise import (cpu_per_second, full_run_check, TOLERANCES,
                                                     write_csv)
from modal_spring_ros.core.auto.measured_error import on_samples, trajectory, trajectory_error
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation, predicted_simulation
from modal_spring_ros.core.threads import stepping_threads
from modal_spring_ros.scenes.resources import load_scene

#: the built-in scenes whose full run converges in a benchmark's time (the 10k and 100k sheets'
#: do not; the cloth's auto takes a minute of planning, in ``--quick`` it is left out)
SCENES = ('chain_2', 'sheet_10x10', 'sheet_10x10_resonance', 'sheet_10x10_swing', 'sheet_32x32',
          'sheet_32x32_resonance', 'cantilever_3d', 'cable_3d', 'soft_block_3d', 'cloth_3d')
QUICK_SCENES = ('sheet_10x10', 'sheet_10x10_resonance', 'sheet_10x10_swing')
MAX_DURATION_S = 5.0
SAMPLE_S = 0.02


def measure(name: str, tolerance: float) -> dict:
    """Check ``name``'s predicted and measured automatic plans at ``tolerance``."""
    scene = load_scene(name)
    duration = min(scene.default_duration, MAX_DURATION_S)
    # the plan per simulated second, against the predicted one: planned unbudgeted
    config = SimulationConfig(auto=True, tolerance=tolerance, horizon_s=duration,
                              planning_share=None)
    row = {'scene': name, 'tolerance': tolerance, 'duration_s': duration}
    start = time.process_time()
    auto = build_simulation(scene, config)
    row['plan_cpu_s'] = time.process_time() - start
    sample_s = auto.dt * max(1, int(round(SAMPLE_S / auto.dt)))
    predicted = on_samples(predicted_simulation(scene, config), sample_s)
    samples = int(round(duration / sample_s))
    checked = full_run_check(scene, sample_s, samples, tolerance)
    if checked is None:
        return dict(row, refused='the reference did not converge')
    reference, baseline, _ = checked
    full_cpu = cpu_per_second(baseline)
    for key, sim in (('predicted', predicted), ('auto', auto)):
        row[f'{key}_method'] = sim.method
        row[f'{key}_coordinates'] = int(sim.coordinates)
        row[f'{key}_error'] = trajectory_error(trajectory(sim, sample_s, samples), reference)
        row[f'{key}_cost'] = cpu_per_second(sim) / full_cpu
    row['printed'] = auto.pilot.error if auto.pilot is not None else math.nan
    return row


@stepping_threads()
def run(quick: bool, progress: Callable[[str], None]) -> dict:
    rows = []
    jobs = [(name, t) for name in (QUICK_SCENES if quick else SCENES) for t in TOLERANCES]
    for k, (name, tolerance) in enumerate(jobs):
        row = measure(name, tolerance)
        rows.append(row)
        what = (row['refused'] if 'refused' in row else
                f"predicted {row['predicted_error']:.2%} at {row['predicted_cost']:.2g} x full; "
                f"auto ({row['auto_method']}) {row['auto_error']:.2%} at "
                f"{row['auto_cost']:.2g} x full")
        progress(f'auto {k + 1}/{len(jobs)}: {name} at {tolerance:.1%}: {what}')
    return {'rows': rows}


def table(results: dict) -> str:
    lines = [f"{'scene':24s} {'T':>5s} {'predicted':>9s} {'cost':>5s} {'auto':>7s} "
             f"{'cost':>5s} {'method':>6s}"]
    for r in results['rows']:
        if 'refused' in r:
            lines.append(f"{r['scene']:24s} {r['tolerance']:5.1%} {r['refused']}")
            continue
        lines.append(f"{r['scene']:24s} {r['tolerance']:5.1%} {r['predicted_error']:9.2%} "
                     f"{r['predicted_cost']:5.2f} {r['auto_error']:7.2%} {r['auto_cost']:5.2f} "
                     f"{r['auto_method']:>6s}")
    return '\n'.join(lines)


def write_outputs(results: dict, out: Path, progress) -> None:
    write_csv(results['rows'], out / 'auto.csv')
    progress(f"wrote {out / 'auto.csv'}")

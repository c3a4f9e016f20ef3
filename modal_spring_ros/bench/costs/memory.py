"""
Scale benchmark: memory, set-up, step and frame as a scene grows, against the memory estimate.

Each size runs in its own child process (so that its peak resident memory is its own): the
scene is built, the run's memory estimated (:mod:`~modal_spring_ros.core.memory_estimate`), the
simulation built (modes, derivative coordinates, spring sample: the set-up, timed), steps timed
as medians, and one frame as the node makes it. The peak is the child's peak resident memory
above what it held before the scene was built. A frame at 60 Hz has 16.7 ms for its steps and its
cloud: the table says which sizes stream at that rate.
"""
from __future__ import annotations

import csv
import math
import os
from pathlib import Path
import resource
import statistics
import time
from typing import Callable

from modal_spring_ros.bench.charts import finish_chart, subplots
from modal_spring_ros.bench.child_run import in_child
from modal_spring_ros.bench.costs.steps import frame_costs
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.memory_estimate import estimate, run_size
from modal_spring_ros.runs.sample_cache import sample_cache
from modal_spring_ros.scenes.fields.limits import available_memory
from modal_spring_ros.scenes.sized import sized_scene

#: The run the scale case measures: the band's 32 lowest rest modes with sampled springs (the
#: large-scene stream), at the sheets' step.
SCALE_CONFIG = {'band': FilterBand('lowpass', 0, 31, 'index'), 'basis': 'rest',
                'forces': 'sampled', 'dt': 1e-4}
#: Sheet sides: 10k to 500k particles (--quick: up to 40k).
SIDES = (100, 224, 316, 500, 707)
QUICK_SIDES = (100, 200)
#: A frame's period at the stream's default rate, s.
FRAME_PERIOD_S = 1.0 / 60.0


def resident_bytes() -> int:
    """Return this process's resident memory now, bytes."""
    with open('/proc/self/statm') as fh:
        return int(fh.read().split()[1]) * os.sysconf('SC_PAGE_SIZE')


def reset_peak() -> None:
    """
    Start this process's peak resident memory afresh (Linux: ``/proc/self/clear_refs``).

    Without it the peak would be the largest since the process started, imports included.
    """
    try:
        with open('/proc/self/clear_refs', 'w') as fh:
            fh.write('5')
    except OSError:
        pass


def peak_bytes() -> int:
    """Return this process's peak resident memory since :func:`reset_peak`, bytes."""
    try:
        with open('/proc/self/status') as fh:
            for line in fh:
                if line.startswith('VmHWM:'):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def measure(kind: str, side: int, config: dict, batches: int = 0, batch_steps: int = 20,
            cached_samples: bool = False) -> dict:
    """
    Build a run of the sized ``kind`` scene, step it, and return its estimate, peak and costs.

    In this process: call it in a fresh one (:func:`measure_in_child`) for a peak of its own.
    ``batches`` 0: the set-up and a first batch of steps, untimed (no steps or frame timed).
    """
    reset_peak()
    before = resident_bytes()
    scene = sized_scene(kind, side)
    sim_config = SimulationConfig(**config)
    expected = estimate(run_size(scene, sim_config))
    start = time.perf_counter()
    sim = build_simulation(scene, sim_config,
                           samples=sample_cache() if cached_samples else None,
                           memory_available=available_memory())
    setup_s = time.perf_counter() - start
    result = {'kind': kind, 'side': side, 'particles': scene.n_particles,
              'estimate_mb': expected.total / 1e6, 'estimate': expected.text(),
              'setup_s': setup_s}
    sim.step(batch_steps)
    if batches:
        times = []
        for _ in range(batches):
            t0 = time.perf_counter()
            sim.step(batch_steps)
            times.append((time.perf_counter() - t0) / batch_steps)
        step_s = statistics.median(times)
        frame = frame_costs(sim, batches)
        per_frame_s = FRAME_PERIOD_S / sim.dt * step_s + frame['frame_total_us'] * 1e-6
        result.update(step_us=step_s * 1e6, frame_us=frame['frame_total_us'], dt=sim.dt,
                      frame_load=per_frame_s / FRAME_PERIOD_S)
    result['peak_mb'] = (peak_bytes() - before) / 1e6
    result['estimate_over_peak'] = result['estimate_mb'] / result['peak_mb']
    return result


def measure_in_child(kind: str, side: int, config: dict, batches: int = 0,
                     batch_steps: int = 20, cached_samples: bool = False) -> dict:
    """
    :func:`measure` in a fresh process, so that its peak memory is the run's own.

    :raises ChildFailed: (a ``RuntimeError``) the measure raised, or its process ended without
        an answer.
    """
    return in_child(measure, kind, side, config, batches, batch_steps, cached_samples,
                    what=f'{kind} {side}')


def run(quick: bool, progress: Callable[[str], None]) -> list[dict]:
    sides = QUICK_SIDES if quick else SIDES
    results = []
    for k, side in enumerate(sides):
        progress(f'scale {k + 1}/{len(sides)}: sheet {side} x {side} ({side * side:,} '
                 'particles): set-up, steps, frame')
        try:
            results.append(measure_in_child('sheet', side, SCALE_CONFIG,
                                            batches=5 if quick else 15))
        except RuntimeError as exc:  # refused (the estimate beyond the memory available)
            progress(str(exc))
            results.append({'particles': side * side, 'error': str(exc)})
    return results


def table(results: list[dict]) -> str:
    lines = [f"{'particles':>10s} {'estimate MB':>12s} {'peak MB':>8s} {'est/peak':>8s} "
             f"{'set-up s':>9s} {'us/step':>8s} {'us/frame':>9s} {'60 Hz load':>10s}"]
    for r in results:
        if 'error' in r:
            lines.append(f"{r['particles']:10,d} {r['error']}")
            continue
        lines.append(f"{r['particles']:10,d} {r['estimate_mb']:12.0f} {r['peak_mb']:8.0f} "
                     f"{r['estimate_over_peak']:8.2f} {r['setup_s']:9.1f} {r['step_us']:8.1f} "
                     f"{r['frame_us']:9.0f} {r['frame_load']:10.2f}")
    streaming = [r['particles'] for r in results if r.get('frame_load', math.inf) <= 1.0]
    lines.append('60 Hz in real time (steps and cloud within a frame period, one core): up to '
                 + (f'{max(streaming):,} particles' if streaming else 'none of these sizes'))
    return '\n'.join(lines)


def write_outputs(results: list[dict], out: Path, progress) -> None:
    """Write ``scale.csv`` and ``scale.png`` (estimate and measured peak against size)."""
    out = Path(out)
    keys = ['particles', 'estimate_mb', 'peak_mb', 'estimate_over_peak', 'setup_s', 'step_us',
            'frame_us', 'frame_load', 'estimate', 'error']
    with open(out / 'scale.csv', 'w', newline='') as fh:
        writer = csv.DictWriter(fh, fieldnames=keys, extrasaction='ignore')
        writer.writeheader()
        writer.writerows(results)
    fig, ax = subplots(figsize=(6, 4))
    measured = [r for r in results if 'error' not in r]
    n = [r['particles'] for r in measured]
    ax.plot(n, [r['peak_mb'] for r in measured], 'o-', label='measured peak')
    ax.plot(n, [r['estimate_mb'] for r in measured], 's--', label='estimate (refused above '
            'the memory available)')
    finish_chart(fig, ax, out / 'scale.png', 'particles', 'resident memory above start, MB',
                 'Memory of a run as the sheet grows (32 modes, sampled springs)')
    progress(f'wrote {out / "scale.csv"} and {out / "scale.png"}')

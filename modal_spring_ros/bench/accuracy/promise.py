"""
The automatic choice's promise on scenes nobody tuned it on: measured error against tolerance.

For each seed of :func:`~modal_spring_ros.scenes.generator.random_scene` and each tolerance
``T``, ``modal.auto`` plans a run of ``DURATION_S`` as ``modal_spring_sim --auto --duration``
does (its planning budgeted: :mod:`~modal_spring_ros.core.auto.budget`; its pilot measures the
plan: :mod:`~modal_spring_ros.core.auto.pilot`). The plan is then checked independently of the
pilot: its error against the full run converged in its step (to a tenth of ``T``), and what a
user pays for the whole run, planning included (``auto_whole_s``: the CPU time of planning and
of stepping the run), against the full run at its default step (the one ``--method full``
takes: ``default_whole_s``, its build and its run) and at the longest step that meets ``T``
(halved from 0.9 of its stability limit: ``at_t_whole_s``), all timed in the same process one
after the other; and as whole processes, the way a user pays it (``process_auto_s`` and
``process_default_s``: ``modal_spring_sim --auto`` and ``--method full`` on the scene written to
a file, interpreter, imports and all). Each scene runs in a worker process with single-threaded
BLAS (two at a time).

Results: ``promise.json``, ``promise.csv`` and ``promise.png`` (achieved against printed
error, and the cost against the full run's, per tolerance).
"""
from __future__ import annotations

import csv
import math
import multiprocessing as mp
import os
from pathlib import Path
import time
from typing import Callable

from modal_spring_ros.bench.charts import subplots
from modal_spring_ros.bench.child_run import pooled
from modal_spring_ros.bench.costs.cli_runs import process_costs
from modal_spring_ros.core.auto.measured_error import (converged_trajectory, on_samples,
                                                       trajectory, trajectory_error,
                                                       WINDOW_ALLOWANCE, worst_window)
from modal_spring_ros.core.auto.work_model import work_per_second
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.simulations import Simulation
from modal_spring_ros.runs.sample_cache import sample_cache
from modal_spring_ros.scenes.generator import random_scene
import numpy as np

SEEDS, QUICK_SEEDS = 50, 6
TOLERANCES = (0.01, 0.003)
DURATION_S, SAMPLE_S = 3.0, 0.02
MAX_PARTICLES = 80
#: CPU time per simulated second is measured over this much simulated time
TIMED_S = 1.0
#: the reference's own error, as a share of the tolerance
REFERENCE_ACCURACY = 0.1
#: the converged reference halves its step at most this many times (a scene whose full run
#: does not converge by then is reported, not waited for)
REFERENCE_HALVINGS = 5
WORKERS = 2


def cpu_per_second(sim: Simulation, simulated_s: float = TIMED_S) -> float:
    """Return the CPU seconds ``sim`` takes per simulated second (from rest)."""
    sim.reset()
    steps = max(1, int(round(simulated_s / sim.dt)))
    start = time.process_time()
    sim.step(steps)
    spent = time.process_time() - start
    sim.reset()
    return spent / (steps * sim.dt)


def measure(seed: int, tolerance: float) -> dict:
    """Plan ``random_scene(seed)`` automatically at ``tolerance`` and check the plan."""
    return check_scene(random_scene(seed, MAX_PARTICLES), seed, (tolerance,), DURATION_S)[0]


def check_scene(scene, seed: int, tolerances: tuple[float, ...], duration_s: float,
                progress: Callable[[str], None] = lambda msg: None) -> list[dict]:
    """
    Plan ``scene`` automatically at each of ``tolerances`` for ``duration_s``, check each plan.

    One truth serves every tolerance: the full run converged to ``REFERENCE_ACCURACY`` of the
    smallest. A row per tolerance (``refused`` says why where a plan or the truth is missing).
    What the whole run costs is measured in this process (planning and the run's stepping,
    against the full run's build and stepping) and as a user pays it:
    ``modal_spring_sim --auto`` against ``--method full``, each a process of its own
    (:func:`~modal_spring_ros.bench.costs.cli_runs.process_costs`).
    """
    base = {'seed': seed, 'scene': scene.name, 'particles': scene.n_particles,
            'dimension': scene.dimension, 'turning': bool(scene.anchor_motion.rotates),
            'damping': float(scene.damping.ratio), 'duration_s': duration_s, 'refused': ''}
    rows, truth = [], None
    for tolerance in sorted(tolerances, reverse=True):
        row = dict(base, tolerance=tolerance)
        rows.append(row)
        progress(f'{scene.name}: planning at {tolerance:.1%} for {duration_s:.3g} s')
        start = time.process_time()
        try:
            sim = build_simulation(scene, SimulationConfig(auto=True, tolerance=tolerance,
                                                           horizon_s=duration_s),
                                   samples=sample_cache())
        except ValueError as exc:
            row['refused'] = str(exc)
            continue
        row['plan_cpu_s'] = time.process_time() - start
        pilot = sim.pilot
        row.update(method=sim.method, coordinates=int(sim.coordinates), dt=float(sim.dt),
                   printed=float(pilot.error) if pilot is not None else math.nan,
                   against=pilot.against if pilot is not None else '')
        if truth is None:
            progress(f'{scene.name}: the full run converged in its step over {duration_s:.3g} s')
            sample_s = sim.dt * max(1, int(round(SAMPLE_S / sim.dt)))
            samples = int(round(duration_s / sample_s))
            full = build_simulation(scene, SimulationConfig(method='full'))
            found = converged_trajectory(lambda dt: on_samples(full, sample_s, dt),
                                         0.2 * full.stability_limit(), sample_s, samples,
                                         REFERENCE_ACCURACY * min(tolerances),
                                         reference_cap(full, sample_s))
            if found is None:
                row['refused'] = (f'the reference did not converge within {REFERENCE_HALVINGS} '
                                  'halvings of its step')
                break
            truth = (found[0], full, sample_s)
        reference, full, sample_s = truth
        samples = len(reference)
        run = on_samples(sim, sample_s)
        achieved = trajectory(run, sample_s, samples)
        row['achieved'] = trajectory_error(achieved, reference)
        row['worst_window'] = worst_window(achieved, reference, sample_s)
        baseline, error = longest_meeting(full, reference, sample_s, tolerance)
        row.update(full_dt=float(baseline.dt), full_error=error,
                   auto_cpu_per_s=cpu_per_second(sim), full_cpu_per_s=cpu_per_second(baseline))
        row['cost_ratio'] = row['auto_cpu_per_s'] / row['full_cpu_per_s']
        start = time.process_time()
        default = build_simulation(scene, SimulationConfig(method='full'))
        built_s = time.process_time() - start
        by_default = trajectory(on_samples(default, sample_s), sample_s, samples)
        row.update(default_dt=float(default.dt),
                   default_error=trajectory_error(by_default, reference),
                   default_window=worst_window(by_default, reference, sample_s))
        row['auto_whole_s'] = row['plan_cpu_s'] + row['auto_cpu_per_s'] * duration_s
        row['default_whole_s'] = built_s + cpu_per_second(default) * duration_s
        row['at_t_whole_s'] = built_s + row['full_cpu_per_s'] * duration_s
        row['whole_vs_default'] = row['auto_whole_s'] / row['default_whole_s']
        row['whole_vs_at_t'] = row['auto_whole_s'] / row['at_t_whole_s']
        # what a user pays: modal_spring_sim as a process, --auto and --method full
        progress(f'{scene.name}: modal_spring_sim --auto and --method full as processes')
        row['process_auto_s'], row['process_default_s'] = process_costs(scene, tolerance,
                                                                        duration_s)
        row['process_vs_default'] = row['process_auto_s'] / row['process_default_s']
    return rows


def reference_cap(full: Simulation, sample_s: float) -> float:
    """
    Return what the converged reference may cost (modelled us per simulated second).

    Its step halved ``REFERENCE_HALVINGS`` times from a fifth of the stability limit.
    """
    first = work_per_second(on_samples(full, sample_s, 0.2 * full.stability_limit()))
    return first * (2 ** (REFERENCE_HALVINGS + 1) - 1) * (1.0 + 1e-9)


def longest_meeting(full: Simulation, reference: np.ndarray, sample_s: float,
                    tolerance: float) -> tuple[Simulation, float]:
    """Return the full run at the longest step (halved from 0.9 of its limit) within T."""
    step = 0.9 * full.stability_limit()
    while True:
        baseline = on_samples(full, sample_s, step)
        error = trajectory_error(trajectory(baseline, sample_s, len(reference)), reference)
        if error <= tolerance or step < 1e-6:
            return baseline, error
        step = baseline.dt / 2.0


def full_run_check(scene, sample_s: float, samples: int, tolerance: float
                   ) -> tuple[np.ndarray, Simulation, float] | None:
    """
    Return the truth a plan is checked against, and the full run that meets ``tolerance``.

    The full run converged in its step to ``REFERENCE_ACCURACY`` of the tolerance (its
    trajectory every ``sample_s``), the full run at the longest step (halved from 0.9 of its
    stability limit) within the tolerance, and that run's error; None where the reference does
    not converge.
    """
    full = build_simulation(scene, SimulationConfig(method='full'))
    found = converged_trajectory(lambda dt: on_samples(full, sample_s, dt),
                                 0.2 * full.stability_limit(), sample_s, samples,
                                 REFERENCE_ACCURACY * tolerance)
    if found is None:
        return None
    return (found[0], *longest_meeting(full, found[0], sample_s, tolerance))


def converged_reference(scene, sample_s: float, samples: int, tolerance: float,
                        progress: Callable[[str], None]) -> tuple[np.ndarray, Simulation, float]:
    """:func:`full_run_check`, said in ``progress``; raises where the reference cannot converge."""
    progress(f'{scene.name}: the full run converged in its step over {samples * sample_s:g} s')
    checked = full_run_check(scene, sample_s, samples, tolerance)
    if checked is None:
        raise RuntimeError(f'{scene.name}: the reference did not converge')
    return checked


def _measure(args: tuple[int, float]) -> list[dict]:
    return [measure(*args)]


def run(quick: bool, progress: Callable[[str], None]) -> dict:
    jobs = [(seed, t) for seed in range(QUICK_SEEDS if quick else SEEDS) for t in TOLERANCES]
    return in_workers(_measure, jobs, 'promise', progress)


def in_workers(measure_job: Callable, jobs: list, suite: str,
               progress: Callable[[str], None]) -> dict:
    """
    Run ``measure_job`` on each of ``jobs`` in ``WORKERS`` processes, single-threaded BLAS.

    Each job gives a list of rows; the rows of every job, sorted by tolerance and seed, with
    their :func:`summary`.
    """
    saved = {k: os.environ.get(k) for k in ('OPENBLAS_NUM_THREADS', 'OMP_NUM_THREADS')}
    os.environ.update(OPENBLAS_NUM_THREADS='1', OMP_NUM_THREADS='1')   # in the workers
    rows = []
    try:
        with mp.get_context('spawn').Pool(WORKERS) as pool:
            for k, found in enumerate(pooled(pool, measure_job, jobs, suite)):
                rows.extend(found)
                for row in found:
                    what = (f"refused ({row['refused'][:60]})" if row['refused'] else
                            f"{row['method']}, measured {row['achieved']:.2%}, printed "
                            f"{row['printed']:.2%}, whole run {row['whole_vs_default']:.2g} x "
                            'the full run at its default step')
                    progress(f"{suite} {k + 1}/{len(jobs)}: seed {row['seed']} at "
                             f"{row['tolerance']:.1%}: {what}")
    finally:
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value
    rows.sort(key=lambda r: (r['tolerance'], r['seed']))
    return {'rows': rows, 'summary': summary(rows)}


def summary(rows: list[dict]) -> list[dict]:
    """Per tolerance: how many met it, the worst ratio to it, refusals, cost against full."""
    out = []
    for t in sorted({r['tolerance'] for r in rows}, reverse=True):
        mine = [r for r in rows if r['tolerance'] == t]
        ran = [r for r in mine if not r['refused']]
        achieved = np.array([r['achieved'] for r in ran])
        cost = np.array([r['cost_ratio'] for r in ran])
        whole = np.array([r['whole_vs_at_t'] for r in ran])
        # against the full run at its default step where that run keeps the promise (the
        # acceptance): within T over the run, and within the allowance in every window
        keeps = [r for r in ran if r['default_error'] <= t
                 and r.get('default_window', 0.0) <= WINDOW_ALLOWANCE * t]
        meets = np.array([r['whole_vs_default'] for r in keeps])
        process = np.array([r['process_vs_default'] for r in keeps if 'process_vs_default' in r])
        out.append({
            'tolerance': t, 'scenes': len(mine), 'refused': len(mine) - len(ran),
            'within_t': float(np.mean(achieved <= t)) if ran else math.nan,
            'within_2t': float(np.mean(achieved <= 2 * t)) if ran else math.nan,
            'windows_within_2t': float(np.mean([r.get('worst_window', math.inf)
                                                <= WINDOW_ALLOWANCE * t
                                                for r in ran])) if ran else math.nan,
            'worst_ratio': float(achieved.max() / t) if ran else math.nan,
            'full_chosen': sum(r['method'] == 'full' for r in ran),
            'median_cost_ratio': float(np.median(cost)) if ran else math.nan,
            'max_cost_ratio': float(cost.max()) if ran else math.nan,
            'median_whole_vs_at_t': float(np.median(whole)) if ran else math.nan,
            'max_whole_vs_at_t': float(whole.max()) if ran else math.nan,
            'default_meets_t': int(meets.size),
            'median_whole_vs_default': float(np.median(meets)) if meets.size else math.nan,
            'within_1_2_of_default': int(np.sum(meets <= 1.2)),
            'max_whole_vs_default': float(meets.max()) if meets.size else math.nan,
            'median_process_vs_default': float(np.median(process)) if process.size else math.nan,
            'process_within_1_2_of_default': int(np.sum(process <= 1.2)),
            'max_process_vs_default': float(process.max()) if process.size else math.nan})
    return out


def table(results: dict) -> str:
    lines = [f"{'T':>6s} {'scenes':>6s} {'refused':>7s} {'<= T':>6s} {'<= 2T':>6s} "
             f"{'windows <= 2T':>13s} {'worst/T':>7s} {'full':>5s} "
             f"{'whole/default (n) median':>24s} {'<= 1.2':>6s} {'max':>6s} "
             f"{'whole/at T median':>17s} {'max':>6s} "
             f"{'process/default median':>22s} {'<= 1.2':>6s} {'max':>6s}"]
    for s in results['summary']:
        lines.append(f"{s['tolerance']:6.1%} {s['scenes']:6d} {s['refused']:7d} "
                     f"{s['within_t']:6.0%} {s['within_2t']:6.0%} "
                     f"{s['windows_within_2t']:13.0%} {s['worst_ratio']:7.2f} "
                     f"{s['full_chosen']:5d} "
                     f"{'(' + str(s['default_meets_t']) + ')':>8s} "
                     f"{s['median_whole_vs_default']:15.2f} "
                     f"{s.get('within_1_2_of_default', 0):6d} {s['max_whole_vs_default']:6.2f} "
                     f"{s['median_whole_vs_at_t']:17.2f} {s['max_whole_vs_at_t']:6.2f} "
                     f"{s.get('median_process_vs_default', math.nan):22.2f} "
                     f"{s.get('process_within_1_2_of_default', 0):6d} "
                     f"{s.get('max_process_vs_default', math.nan):6.2f}")
    return '\n'.join(lines)


def write_outputs(results: dict, out: Path, progress, name: str = 'promise') -> None:
    rows = results['rows']
    write_csv(rows, out / f'{name}.csv')
    progress(f"wrote {out / f'{name}.csv'} and {chart(rows, out / f'{name}.png')}")


def write_csv(rows: list[dict], path: Path) -> None:
    """Write ``rows`` as a CSV file, a column per key any row has (empty where it has none)."""
    keys = sorted({k for r in rows for k in r})
    with open(path, 'w', newline='') as f:
        writer = csv.DictWriter(f, fieldnames=keys)
        writer.writeheader()
        writer.writerows(rows)


def chart(rows: list[dict], path: Path) -> Path:
    """Achieved against printed error, and achieved error against cost, per tolerance."""
    fig, (left, right) = subplots(1, 2, figsize=(11, 4.5))
    for k, t in enumerate(sorted({r['tolerance'] for r in rows}, reverse=True)):
        ran = [r for r in rows if r['tolerance'] == t and not r['refused']]
        color = f'C{k}'
        printed = np.array([max(r['printed'], 1e-6) for r in ran])
        achieved = np.array([max(r['achieved'], 1e-6) for r in ran])
        cost = np.array([r['whole_vs_default'] for r in ran])
        left.scatter(printed, achieved, s=14, color=color, label=f'T = {t:.1%}')
        right.scatter(cost, achieved, s=14, color=color, label=f'T = {t:.1%}: in process')
        timed = [r for r in ran if 'process_vs_default' in r]
        if timed:
            right.scatter([r['process_vs_default'] for r in timed],
                          [max(r['achieved'], 1e-6) for r in timed], s=22, facecolors='none',
                          edgecolors=color, label=f'T = {t:.1%}: modal_spring_sim processes')
        for ax in (left, right):
            ax.axhline(t, color=color, lw=0.8)
            ax.axhline(2 * t, color=color, lw=0.8, ls='--')
    lo, hi = 1e-6, 0.1
    left.plot([lo, hi], [lo, hi], color='0.6', lw=0.8, label='achieved = printed')
    right.axvline(1.0, color='0.6', lw=0.8, label='the full run at its default step')
    for ax, xlabel, title in (
            (left, 'error printed by the pilot', 'measured over the run against printed'),
            (right, "whole run's CPU (planning included) / the full run's at its default step",
             'error against what a run costs')):
        ax.set_xscale('log')
        ax.set_yscale('log')
        ax.set_xlabel(xlabel)
        ax.set_ylabel('error against the converged full run')
        ax.set_title(title)
        ax.legend(fontsize=7)
    fig.suptitle(f'modal.auto on {len({r["scene"] for r in rows})} random scenes '
                 '(solid: T, dashed: 2 T)')
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path

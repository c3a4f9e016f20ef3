"""
The watch between its windows: a plan's motion outgrowing what was measured, caught as it runs.

``sheet_10x10`` shaken ever harder near its vertical mode (3 cm at 9.5 Hz, ramped in over 12 s)
at 1 %: its plan's error against the full run converged in its step, each quarter second from
rest (what the run would be off, unwatched); the run's motion (its mass-weighted displacement
and velocity) against twice the largest its windows measured, the sentinel's threshold; and the
windows its watch stepped, never due (the interval longer than the run): the sentinel's, those
that followed while the error headed beyond the tolerance, the one that fell back, and the
fallback's twin (:mod:`~modal_spring_ros.core.auto.watch.sentinel`).
"""
from __future__ import annotations

import csv
import dataclasses
from pathlib import Path
from typing import Callable

from modal_spring_ros.bench.charts import subplots
from modal_spring_ros.core.auto.measured_error import (trajectory, trajectory_windows,
                                                       WINDOW_ALLOWANCE)
from modal_spring_ros.core.auto.watch.run_watch import RunWatch
from modal_spring_ros.core.auto.watch.sentinel import RISE
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.model.scene import Scene
from modal_spring_ros.scenes.files.writing import scene_to_dict
from modal_spring_ros.scenes.resources import load_scene
from modal_spring_ros.scenes.schema import scene_from_dict
import numpy as np

TOLERANCE = 0.01
RUN_S = 9.0
#: the watch's interval: longer than the run, so that no window is ever due
NEVER_S = 1000.0
#: what the CSV says of each window
FIELDS = ('start_s', 'window_s', 'error', 'worst', 'heading', 'within', 'rising', 'against',
          'cause', 'run')


def shaken_harder() -> Scene:
    """Return ``sheet_10x10`` shaken near its vertical mode ever harder: 3 cm by 12 s."""
    data = scene_to_dict(load_scene('sheet_10x10'))
    data.update(name='sheet_10x10_shaken_harder', anchor_motion=[
        {'axis': 'x', 'amplitude': 0.02, 'frequency_hz': 0.7, 'ramp_s': 1.0},
        {'axis': 'z', 'amplitude': 0.03, 'frequency_hz': 9.5, 'ramp_s': 12.0}])
    return scene_from_dict(data, source='sheet_10x10 shaken harder')


def plan_of(scene: Scene):
    """Return the automatic plan of ``scene`` at ``TOLERANCE``, its planning unbudgeted."""
    return build_simulation(scene, SimulationConfig(auto=True, tolerance=TOLERANCE,
                                                    planning_share=None))


def quarter_errors(plan, duration: float) -> np.ndarray:
    """Return the plan's error from rest against its full reference, each quarter second."""
    reference = plan.watch_reference
    samples = int(round(duration / reference.sample_s))
    run = trajectory(plan.with_dt(plan.dt), reference.sample_s, samples)
    truth = trajectory(reference.reference(), reference.sample_s, samples)
    return trajectory_windows(run, truth, reference.sample_s)


def watched_run(plan, duration: float) -> tuple[list[dict], dict]:
    """
    Run ``plan`` watched (never due) for ``duration``; return its windows and its motion trace.

    The trace: the motion's sizes at each of the sentinel's samples, with its envelope then.
    """
    watch = RunWatch(plan.watch_reference, NEVER_S, run_s=duration)
    sentinel, sample_s = watch.sentinel, plan.watch_reference.sample_s
    sim, current, windows = plan.with_dt(plan.dt), watch, []
    trace = {'t': [], 'displacement': [], 'velocity': [], 'measured_displacement': [],
             'measured_velocity': []}
    next_sample = 0.0
    while sim.time < duration - 0.5 * sim.dt:
        if current is not None:
            measured = sim.method
            sim, window = current.before_step(sim)
            if window is not None:
                windows.append({**dataclasses.asdict(window), 'within': window.within,
                                'rising': window.rising, 'run': measured})
                if not window.within:
                    current = current.after_fallback(sim)
        sim.step()
        if sim.time >= next_sample - 0.5 * sim.dt and sentinel.envelope is not None:
            next_sample += sample_s
            size = sim.motion_size()
            for key, value in zip(('t', 'displacement', 'velocity', 'measured_displacement',
                                   'measured_velocity'), (sim.time, *size, *sentinel.envelope)):
                trace[key].append(float(value))
    return windows, trace


def run(quick: bool, progress: Callable[[str], None]) -> dict:
    """Measure the shaken sheet's plan unwatched and watched (``quick``: the same, 9 s)."""
    progress('watch: sheet_10x10 shaken harder at 1 %: the plan')
    plan = plan_of(shaken_harder())
    progress('watch: its error each quarter second against the full run, from rest')
    errors = quarter_errors(plan, RUN_S)
    quarter_s = RUN_S / errors.size
    progress('watch: the run watched, never due')
    windows, trace = watched_run(plan, RUN_S)
    beyond = np.flatnonzero(errors > WINDOW_ALLOWANCE * TOLERANCE)
    fell = [w['start_s'] for w in windows if not w['within']]
    return {'tolerance': TOLERANCE, 'run_s': RUN_S, 'plan': plan.describe_basis(),
            'pilot_window_s': plan.watch_reference.window_s, 'quarter_s': quarter_s,
            'quarter_errors': errors.tolist(),
            'passes_2t_s': float(beyond[0] * quarter_s) if beyond.size else None,
            'fell_back_s': fell[0] if fell else None, 'windows': windows, 'trace': trace}


def table(results: dict) -> str:
    lines = [f"plan {results['plan']}; its error passes 2 T in the quarter second from "
             f"{results['passes_2t_s']} s; fell back at {results['fell_back_s']:.3f} s",
             f"{'start, s':>9s} {'error':>8s} {'worst':>8s} {'heading':>8s}  run    cause"]
    for w in results['windows']:
        lines.append(f"{w['start_s']:9.3f} {w['error']:8.2%} {w['worst']:8.2%} "
                     f"{w['heading']:8.2%}  {w['run']:6s} {w['cause'] or 'due'}")
    return '\n'.join(lines)


def write_outputs(results: dict, out: Path, progress) -> None:
    with open(out / 'watch.csv', 'w', newline='') as f:
        writer = csv.DictWriter(f, fieldnames=FIELDS, extrasaction='ignore')
        writer.writeheader()
        writer.writerows(results['windows'])
    progress(f"wrote {out / 'watch.csv'} and {chart(results, out / 'watch.png')}")


def chart(results: dict, path: Path) -> Path:
    """Draw the plan's error each quarter second with the windows, and the sentinel's view."""
    fig, (top, bottom) = subplots(2, 1, figsize=(9, 6.5), sharex=True)
    t = results['tolerance']
    errors = np.array(results['quarter_errors'])
    edges = np.arange(errors.size + 1) * results['quarter_s']
    top.stairs(np.maximum(errors, 1e-5), edges, color='k', label='the plan, unwatched')
    top.axhline(t, color='C2', lw=1, ls='--', label='T')
    top.axhline(WINDOW_ALLOWANCE * t, color='C3', lw=1, ls='--', label='2 T')
    top.axvspan(0.0, results['pilot_window_s'], color='0.9', zorder=0,
                label="the pilot's window")
    for w in results['windows']:
        colour = 'C0' if not w['against'] else 'C2' if w['within'] else 'C3'
        top.axvspan(w['start_s'], w['start_s'] + w['window_s'], ymin=0.0, ymax=0.06,
                    color=colour, alpha=0.8)
        top.axvline(w['start_s'], color=colour, lw=1)
    if results['fell_back_s'] is not None:
        top.axvline(results['fell_back_s'], color='C3', lw=2, label='fell back to the full run')
    top.set_yscale('log')
    top.set_ylabel('error each 0.25 s (relative L2)')
    top.set_title('sheet_10x10 shaken harder at 1 %: windows within (green), beyond (red), '
                  "the fallback's twin (blue)", fontsize=9)
    top.legend(fontsize=7, loc='upper left')
    trace = {k: np.array(v) for k, v in results['trace'].items()}
    pilot = min(int(np.searchsorted(trace['t'], results['pilot_window_s'])), trace['t'].size - 1)
    for key, colour in (('displacement', 'C0'), ('velocity', 'C1')):
        largest = trace[f'measured_{key}']
        bottom.plot(trace['t'], trace[key] / largest[pilot], color=colour, lw=0.8,
                    label=f'{key}, sqrt(x^T M x)')
        bottom.plot(trace['t'], RISE * largest / largest[pilot], color=colour, lw=1.2, ls='--',
                    label=f'{RISE:g} x the largest measured')
    bottom.set_yscale('log')
    bottom.set_ylim(1e-2, None)
    bottom.set_xlim(0.0, results['run_s'])
    bottom.set_xlabel('simulated time, s')
    bottom.set_ylabel("motion / the pilot's largest")
    bottom.legend(fontsize=7, loc='upper left')
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path

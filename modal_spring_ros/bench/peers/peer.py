"""
The project against a peer: Newton's semi-implicit run on the resonance scenes, at 1 % error.

On each scene of :data:`SCENES` (shaken at a resonance: large deformation), over the scene's run,
every run is checked as the promise suite checks a plan: the relative L2 error of the
displacement against the full run converged in its step (:func:`~modal_spring_ros.bench.
promise.full_run_check`), and its CPU seconds per simulated second, one after the other in one
process with one BLAS thread:

- ``newton``: Newton's ``SolverSemiImplicit`` (:mod:`~modal_spring_ros.bench.peers.newton_peer`) at
  0.9 of the explicit stability limit on the sample grid and at its halves, until one meets the
  tolerance;
- ``full``: the project's full explicit run at the longest step that meets it;
- ``auto``: ``--auto --tolerance 0.01`` planned for the run;
- ``N modes + derivatives``: the band of the lowest ``N`` rest modes with their derivatives, at
  the default step with every spring, and with sampled springs at the default step and its
  halves (a derivative coordinate's frequency can sit near the stability limit, where the
  explicit step's phase error grows over a long run).

The figure: the cheapest Newton run within the tolerance, and the cheapest of the project's runs
at equal or better error (its error at most that Newton run's), as a ratio of CPU time. And what
users pay, whole processes (:func:`process_figures`): ``modal_spring_sim --auto`` over the run
(its first run, which solves for its modes, and its second, which reads them from its cache)
against Newton's cheapest run as a script (:mod:`~modal_spring_ros.bench.peers.newton_process`,
Warp's kernels from its cache, as the in-process runs left it). Where Newton is not installed
its rows are skipped with a note. Results: ``peer.json``, ``peer.csv`` and ``peer.png`` (error
against cost).
"""
from __future__ import annotations

import math
from pathlib import Path
import sys
import tempfile
from typing import Callable

from modal_spring_ros.bench.accuracy.promise import converged_reference, cpu_per_second, write_csv
from modal_spring_ros.bench.charts import subplots
from modal_spring_ros.bench.costs.cli_runs import cli_cpu_seconds, cpu_seconds, process_env
from modal_spring_ros.bench.peers import newton_peer
from modal_spring_ros.core.auto.measured_error import on_samples, trajectory, trajectory_error
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.threads import stepping_threads
from modal_spring_ros.runs.sample_cache import sample_cache
from modal_spring_ros.scenes.resources import load_scene

SCENES = ('sheet_32x32_resonance', 'sheet_10x10_resonance')
#: the quick suite: the finer scene over its first seconds
QUICK_SCENES, QUICK_DURATION_S = ('sheet_32x32_resonance',), 1.5
TOLERANCE = 0.01
SAMPLE_S = 0.01
#: the bands (lowest N rest modes) stepped with their derivatives
BANDS = (16, 24, 32)
#: the sampled runs of each band at its default step and this many halves of it
BAND_HALVINGS = 2
#: the peer's step: this share of the stability limit, then halves of it
PEER_START, PEER_HALVINGS = 0.9, 4
#: the cost the issue asks the project to beat the peer by
GOAL = 3.0


def _row(run: str, coordinates: int, dt: float, error: float, cpu: float) -> dict:
    return {'run': run, 'coordinates': int(coordinates), 'dt': float(dt), 'error': error,
            'cpu_per_s': cpu}


def peer_rows(scene, reference, samples: int, limit: float, duration: float,
              progress: Callable[[str], None]) -> list[dict]:
    """Newton's runs from 0.9 of the limit down, until one meets the tolerance."""
    rows = []
    step = PEER_START * limit
    for _ in range(PEER_HALVINGS + 1):
        dt = SAMPLE_S / max(1, math.ceil(SAMPLE_S / step - 1e-9))
        progress(f'{scene.name}: Newton semi-implicit at dt {dt:.3g} s')
        peer = newton_peer.NewtonRun(scene, dt)     # the trajectory warms Warp's kernels up
        error = trajectory_error(trajectory(peer, SAMPLE_S, samples), reference)
        rows.append(_row('newton', peer.coordinates, dt, error,
                         cpu_per_second(peer, duration) if math.isfinite(error) else math.nan))
        if error <= TOLERANCE:
            break
        step = dt / 2.0
    return rows


@stepping_threads()         # one BLAS thread, as the node and modal_spring_sim step
def measure(scene_name: str, duration: float | None, progress: Callable[[str], None]) -> dict:
    """Return every run's error and cost on ``scene_name`` over ``duration`` (the scene's)."""
    scene = load_scene(scene_name)
    duration = duration or scene.default_duration
    samples = int(round(duration / SAMPLE_S))
    reference, full, full_error = converged_reference(scene, SAMPLE_S, samples, TOLERANCE,
                                                      progress)
    rows = [_row('full', full.coordinates, full.dt, full_error, cpu_per_second(full, duration))]

    def ours(name: str, config: SimulationConfig) -> None:
        progress(f'{scene_name}: {name}')
        sim = on_samples(build_simulation(scene, config, samples=sample_cache()), SAMPLE_S)
        error = trajectory_error(trajectory(sim, SAMPLE_S, samples), reference)
        rows.append(_row(name, sim.coordinates, sim.dt, error,
                         cpu_per_second(sim, duration) if math.isfinite(error) else math.nan))

    # the plan's cost per simulated second: planned unbudgeted (its planning is not compared)
    ours('auto', SimulationConfig(auto=True, tolerance=TOLERANCE, horizon_s=duration,
                                  planning_share=None))
    for count in BANDS:
        band = FilterBand('lowpass', 0, count - 1, 'index')
        ours(f'{count} modes + derivatives, exact springs',
             SimulationConfig(band=band, basis='derivatives'))
        step = None            # the default step, then its halves
        for _ in range(BAND_HALVINGS + 1):
            sampled = SimulationConfig(band=band, basis='derivatives', forces='sampled', dt=step)
            ours(f'{count} modes + derivatives, sampled springs', sampled)
            step = rows[-1]['dt'] / 2.0
    refused = newton_peer.refusal(scene) if newton_peer.AVAILABLE else newton_peer.MISSING
    if not refused:
        rows += peer_rows(scene, reference, samples, full.stability_limit(), duration,
                          progress)
    found = figure(rows)
    processes = {}
    if found:
        progress(f'{scene_name}: modal_spring_sim --auto and Newton as whole processes')
        processes = process_figures(scene_name, duration, found['peer_run']['dt'])
    return {'scene': scene_name, 'particles': scene.n_particles, 'duration_s': duration,
            'tolerance': TOLERANCE, 'peer': '' if refused else 'newton', 'peer_note': refused,
            'rows': rows, 'figure': found, 'processes': processes}


def process_figures(scene_name: str, duration: float, newton_dt: float) -> dict:
    """
    Return what ``--auto`` and Newton's run at ``newton_dt`` cost as whole processes, CPU s.

    ``modal_spring_sim --auto`` twice with a cache of its own (``auto_first_s``: its modes
    solved; ``auto_s``: read from the cache, as a user's next run), then Newton's script
    (``newton_s``); ``ratio``: Newton's against the second ``--auto``.
    """
    with tempfile.TemporaryDirectory(prefix='peer_') as folder:
        env = process_env(Path(folder))
        auto = ['--scene', scene_name, '--auto', '--tolerance', repr(TOLERANCE), '--duration',
                repr(float(duration)), '--quiet']
        first, again = cli_cpu_seconds(auto, env), cli_cpu_seconds(auto, env)
        newton = cpu_seconds([sys.executable, '-m', 'modal_spring_ros.bench.peers.newton_process',
                              scene_name, '--duration', repr(float(duration)), '--dt',
                              repr(float(newton_dt))], env)
    return {'auto_first_s': first, 'auto_s': again, 'newton_s': newton, 'ratio': newton / again}


def figure(rows: list[dict]) -> dict:
    """
    Return the peer's cheapest run within the tolerance and the project's at its error or better.

    With the ratio of their CPU time per simulated second (empty where a side has no such run).
    """
    peer = min((r for r in rows if r['run'] == 'newton' and r['error'] <= TOLERANCE),
               key=lambda r: r['cpu_per_s'], default=None)
    if peer is None:
        return {}
    mine = min((r for r in rows if r['run'] != 'newton' and r['error'] <= peer['error']),
               key=lambda r: r['cpu_per_s'], default=None)
    out = {'peer_run': peer, 'ours': mine}
    if mine is not None:
        out['ratio'] = peer['cpu_per_s'] / mine['cpu_per_s']
        out['goal_met'] = out['ratio'] >= GOAL
    return out


def run(quick: bool, progress: Callable[[str], None]) -> dict:
    return {'scenes': [measure(name, QUICK_DURATION_S if quick else None, progress)
                       for name in (QUICK_SCENES if quick else SCENES)]}


def table(results: dict, extra: Callable[[dict], list[str]] = lambda res: [],
          verdict: Callable[[dict], str] | None = None) -> str:
    """
    Return every scene's runs as a table, ``extra`` lines of it, and the figure's line.

    ``verdict`` says what the project's run at Newton's error is against it (default: the
    goal's ratio).
    """
    lines = []
    for res in results['scenes']:
        lines.append(f"{res['scene']} ({res['particles']} particles), {res['duration_s']:g} s, "
                     f"tolerance {res['tolerance']:.0%}")
        lines.append(f"{'run':<44} {'coords':>6} {'dt (s)':>9} {'error':>8} {'CPU s/s':>9}")
        for r in res['rows']:
            error = f"{r['error']:>8.2%}" if math.isfinite(r['error']) else f"{'-':>8}"
            lines.append(f"{r['run']:<44} {r['coordinates']:>6} {r['dt']:>9.3g} {error} "
                         f"{r['cpu_per_s']:>9.4f}")
        lines += extra(res)
        lines.append(_figure_line(res, verdict or _against_goal))
        lines += _process_lines(res)
    return '\n'.join(lines)


def _process_lines(res: dict) -> list[str]:
    """Say what ``--auto`` and Newton cost as whole processes (none where not measured)."""
    p = res.get('processes') or {}
    if not p:
        return []
    return [f"  whole processes: modal_spring_sim --auto {p['auto_s']:.2f} s of CPU "
            f"({p['auto_first_s']:.2f} s solving its modes), Newton's script "
            f"{p['newton_s']:.2f} s: {p['ratio']:.1f}x cheaper (goal {GOAL:g}x "
            f"{'met' if p['ratio'] >= GOAL else 'not met'})"]


def _figure_line(res: dict, verdict: Callable[[dict], str] | None = None) -> str:
    fig = res['figure']
    if res['peer_note']:
        return f"  no peer: {res['peer_note']}"
    if not fig:
        return '  Newton met the tolerance at none of its steps'
    peer = fig['peer_run']
    head = (f"  Newton within {res['tolerance']:.0%}: dt {peer['dt']:.3g} s, "
            f"{peer['error']:.2%}, {peer['cpu_per_s']:.4f} CPU s/s; ")
    if fig['ours'] is None:
        return head + 'no run of the project at that error or better'
    return head + (verdict or _against_goal)(fig)


def _against_goal(fig: dict) -> str:
    mine = fig['ours']
    return (f"{mine['run']} at {mine['error']:.2%}: {fig['ratio']:.1f}x cheaper "
            f"(goal {GOAL:g}x {'met' if fig['goal_met'] else 'not met'})")


def write_outputs(results: dict, out: Path, progress, name: str = 'peer',
                  title: str | None = None) -> None:
    """Write every scene's rows as ``<name>.csv`` and their chart as ``<name>.png``."""
    rows = [dict(r, scene=res['scene']) for res in results['scenes'] for r in res['rows']]
    write_csv(rows, out / f'{name}.csv')
    path = (chart(results, out / f'{name}.png') if title is None
            else chart(results, out / f'{name}.png', title))
    progress(f"wrote {out / f'{name}.csv'} and {path}")


def chart(results: dict, path: Path, title: str = "The project against Newton's semi-implicit "
          'run (sampled runs: the default step and its halves)') -> Path:
    """Error against CPU per simulated second, a panel per scene: a colour per kind of run."""
    scenes = results['scenes']
    fig, axes = subplots(1, len(scenes), figsize=(6.5 * len(scenes), 5), squeeze=False)
    for ax, res in zip(axes[0], scenes):
        shown = [r for r in res['rows']
                 if math.isfinite(r['error']) and math.isfinite(r['cpu_per_s'])]
        for k, name in enumerate(dict.fromkeys(r['run'] for r in shown)):
            mine = [r for r in shown if r['run'] == name]
            peer = name == 'newton'
            ax.plot([r['cpu_per_s'] for r in mine], [max(r['error'], 1e-6) for r in mine],
                    's' if peer else 'o-', color='k' if peer else f'C{k % 10}', ms=5,
                    lw=0.8, label='Newton semi-implicit' if peer else name)
            for r in mine if peer else ():
                ax.annotate(f"{r['dt'] * 1e3:.2g} ms", (r['cpu_per_s'], r['error']),
                            fontsize=7, xytext=(4, 2), textcoords='offset points')
        ax.axhline(res['tolerance'], color='0.6', lw=0.8)
        ax.set_xscale('log')
        ax.set_yscale('log')
        ax.set_xlabel('CPU seconds per simulated second')
        ax.set_ylabel('error against the converged full run')
        ax.set_title(f"{res['scene']}, {res['duration_s']:g} s"
                     + ('' if not res['peer_note'] else '\n(no peer: ' + res['peer_note'] + ')'),
                     fontsize=8)
        ax.legend(fontsize=6)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path

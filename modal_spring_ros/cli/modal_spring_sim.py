"""
``modal_spring_sim``: run a scene headless (no ROS) and save the run as ``.npz``.

Example::

    modal_spring_sim --scene sheet_10x10 --modes 0:14 --duration 2 --output lowpass.npz
    modal_spring_sim --filter lowpass --high-hz 20 --order 4 --gain peak:8:2:6 \
        --response-chart response.png
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import os
import sys
import time

from modal_spring_ros.cli.common import (add_simulation_options, beside_bar, claimed_outputs,
                                         config_from_args, progress_bar, run_main, script_parser,
                                         write_output)
from modal_spring_ros.cli.launcher import install_hint
try:
    from modal_spring_ros.bags.files.capture import RunBagWriter
except ImportError as missing:    # pip install without the ros extra: runs, but no bags
    RunBagWriter = None
    BAGS_MISSING = (f'--bag needs the ROS message packages ({missing.name} is not installed): '
                    f'{install_hint(missing.name or "")}')
from modal_spring_ros.core.auto.watch.run_watch import RunWatch, watch_of, WatchedWindow
from modal_spring_ros.core.config import MAX_HORIZON_S
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.memory_estimate import gib
from modal_spring_ros.runs.frame_store import check_room, frame_count
from modal_spring_ros.runs.response_chart import draw_response
from modal_spring_ros.runs.run import record
from modal_spring_ros.runs.sample_cache import sample_cache
from modal_spring_ros.scenes.fields.limits import available_memory
from modal_spring_ros.scenes.resources import load_scene

PROG = 'modal_spring_sim'


def build_parser() -> argparse.ArgumentParser:
    p = script_parser(PROG, __doc__)
    add_simulation_options(p)
    p.add_argument('--duration', type=float, default=None,
                   help="simulated seconds (default: the scene's)")
    p.add_argument('--frame-every', type=int, default=1,
                   help='keep every N-th step as a frame (default 1: every step)')
    p.add_argument('--output', default=None, help='write the run to this .npz file')
    p.add_argument('--bag', default=None,
                   help='also write every frame to this new rosbag2 MCAP bag folder')
    p.add_argument('--response-chart', default=None, metavar='PNG',
                   help="draw the filter's response (gain against frequency, the scene's "
                        'modes marked) to this PNG file')
    p.add_argument('--allow-unstable', action='store_true',
                   help='step even above the explicit stability limit (to study divergence)')
    p.add_argument('--quiet', action='store_true', help='no progress on stderr')
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)

    def body() -> int:
        if args.bag and RunBagWriter is None:
            raise ValueError(BAGS_MISSING)
        if args.frame_every < 1:
            raise ValueError(f'--frame-every ({args.frame_every}) must be at least 1')
        progress = None if args.quiet else (lambda msg: print(f'[{PROG}] {msg}',
                                                              file=sys.stderr))
        scene = load_scene(args.scene, progress)
        duration = args.duration if args.duration is not None else scene.default_duration
        if not (math.isfinite(duration) and duration > 0):
            raise ValueError(f'--duration ({duration}) must be a positive number of seconds')
        # --auto's tolerance holds over the run asked for (up to a day)
        config = dataclasses.replace(config_from_args(args),
                                     horizon_s=min(duration, MAX_HORIZON_S))
        sim = build_simulation(scene, config, progress=progress,
                               allow_unstable=args.allow_unstable, samples=sample_cache(),
                               memory_available=available_memory())
        with claimed_outputs({'--output': args.output, '--response-chart': args.response_chart},
                             {'--bag': args.bag}):
            if args.response_chart:
                write_output(args.response_chart, '--response-chart', lambda: draw_response(
                    sim.band, sim.basis.frequencies_hz, args.response_chart,
                    f'{scene.name}: {sim.band.describe()}'))
            return run_and_report(sim, config, duration)

    def run_and_report(sim, config, duration: float) -> int:
        bag = None
        if args.bag:
            bag = RunBagWriter(args.bag, sim.model.scene, config, dt=sim.dt,
                               frame_every=args.frame_every, duration=duration)
        if args.output:
            check_room(args.output, frame_count(duration, sim.dt, args.frame_every),
                       sim.model.scene.n_particles, f'--output {args.output}')
        start = time.perf_counter()
        ahead = head_start(sim, duration, keeps_frames=bool(args.output or args.bag))
        run_s = duration - ahead
        watch = watch_of(sim, config.watch_s, run_s=duration, from_s=ahead)
        # simulated seconds done, with the time left (a bar once the run has taken a second)
        shown = progress_bar(PROG, duration, 's', 'simulated', quiet=args.quiet)
        try:
            run = record(sim, run_s, frame_every=args.frame_every,
                         on_progress=lambda fraction: shown(ahead + fraction * run_s),
                         on_frame=bag.frame if bag else None, watch=watch,
                         on_watch=None if args.quiet else
                         lambda window, now: beside_bar(PROG, watched_line(window, now)),
                         keep_frames=bool(args.output),
                         frames_dir=os.path.dirname(os.path.abspath(args.output))
                         if args.output else None)
            shown(run.simulation.time, final=True)
            if bag:
                bag.close()
        except BaseException:  # a full disk, Ctrl-C: no half-written bag is left behind
            if bag:
                bag.writer.discard()
            raise
        wall = time.perf_counter() - start
        sim = run.simulation
        steps = max(sim.steps, 1)
        print(summary(sim, run.diverged, wall / steps, wall, watch, ahead))
        if args.output:
            if not (args.quiet or run.compressed):
                print(f'[{PROG}] writing {args.output}: {run.t.size:,} frames '
                      f'({gib(run.positions.nbytes)}, stored uncompressed)', file=sys.stderr)
            write_output(args.output, '--output', lambda: run.save_npz(args.output))
            print(f'wrote {args.output} ({run.t.size} frames)')
        if args.bag:
            print(f'wrote bag {args.bag} ({run.frames_made} frames)')
        return 1 if run.diverged else 0

    return run_main(PROG, body)


def watched_line(window: WatchedWindow, now) -> str:
    """Say what one watched window measured, and what the run does about it."""
    if window.amplifying:
        return f'WARN: watched: {window.describe()}'
    if window.within:
        return f'watched: {window.describe()}'
    return (f'WARN: watched: {window.describe()}, beyond the tolerance '
            f'{window.tolerance:.2%}: the run falls back to the {now.method} run '
            f'(dt {now.dt:.3g} s) from t = {window.start_s:.4g} s')


def head_start(sim, duration: float, keeps_frames: bool) -> float:
    """
    Go on from where the pilot's own run of ``sim`` ended, where nothing before is kept.

    The automatic choice stepped the run it chose over its check (the full run at that very
    step, from rest): a run that keeps no frame before its last (no ``--output``, no ``--bag``)
    takes that state (:attr:`~modal_spring_ros.core.auto.plan.PilotReport.head_start`) rather
    than stepping the same steps again. Return the simulated seconds it starts at (0: none).
    """
    head = sim.pilot.head_start if sim.pilot is not None else None
    if keeps_frames or head is None or head.time > duration + 0.5 * sim.dt:
        return 0.0
    sim.take_over(head)
    return sim.time


def summary(sim, diverged: str, seconds_per_step: float, wall: float,
            watch: RunWatch | None = None, ahead_s: float = 0.0) -> str:
    scene = sim.model.scene
    lines = [f'scene      {scene.name}: {scene.n_particles} particles, {scene.n_springs} '
             f'springs, {sim.model.n_free_dof} free DOF']
    kept = sim.kept_modes
    if sim.method == 'modal':
        f = sim.basis.frequencies_hz
        lines.append(f'modes      {kept.size} stepped of {sim.basis.count} computed '
                     f'({f[kept].min():.4g} .. {f[kept].max():.4g} Hz)'
                     + ('; band truncated at max_modes' if sim.truncated else ''))
        lines.append(f'band       {sim.band.describe()}')
        lines.append(f'basis      {sim.describe_basis()}: {sim.coordinates} coordinates, '
                     f'computed in {sim.basis_seconds:.3g} s')
    else:
        lines.append(f'method     full physical ({sim.model.n_free_dof} DOF)')
    forces = sim.force_report()
    if forces.model == 'sampled':
        lines.append(f'forces     {forces.description}')
    elif forces.model == 'refreshed':
        lines.append(f'forces     {forces.description}; largest measured error of the '
                     f'continued force {forces.error:.2e}')
    choice = sim.mode_choice
    if choice is not None:
        errors = ', '.join(f'{k} {v:.2%}' for k, v in choice.load_errors.items())
        lines.append(f'auto       {choice.describe()} ({errors})')
    if sim.pilot is not None:
        lines.append(f'measured   {sim.pilot.describe()}')
    if watch is not None:
        fell = watch.last is not None and not watch.last.within
        then = f', watched then: {watch.then.describe()}' if watch.then is not None else ''
        lines.append(f'watched    {watch.describe()}'
                     + (f'; beyond {watch.last.tolerance:.2%}: fell back to the {sim.method} '
                        f'run{then}' if fell else ''))
    ahead = (f" (from t = {ahead_s:.4g} s, where the pilot's run of it ended: not stepped "
             'again)' if ahead_s > 0.0 else '')
    lines.append(f'stepping   {sim.integrator} Newmark, dt {sim.dt:g} s '
                 f'(explicit limit {sim.stability_limit():.4g} s), {sim.steps} steps, '
                 f't = {sim.time:.4g} s{ahead}')
    lines.append(f'speed      {seconds_per_step * 1e6:.1f} us per step, {wall:.2f} s wall, '
                 f'real-time factor {sim.time / max(wall, 1e-12):.1f}')
    lines.append(f'strain     {sim.max_strain():.3%} largest spring strain')
    if diverged:
        lines.append(f'DIVERGED   {diverged}')
    return '\n'.join(lines)


if __name__ == '__main__':
    sys.exit(main())

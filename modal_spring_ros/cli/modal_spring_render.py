"""
``modal_spring_render``: draw a run (a bag or ``.npz``) as an animated GIF or snapshots (PNG).

    modal_spring_render RUN --output sheet.gif [--fps 20] [--start S] [--duration S]
    modal_spring_render RUN --output sheet.png [--snapshots 6]

What the stream looks like without RViz: the sheet seen in its own plane (z up), coloured by
each particle's displacement from rest, the clamp in black. Reads what ``modal_spring_record``,
a node's ``record.bag`` or ``modal_spring_sim --bag/--output`` wrote.
"""
from __future__ import annotations

import math
import sys

from modal_spring_ros.bags.files.run_loading import load_run
from modal_spring_ros.cli.common import (claimed_outputs, progress_bar, run_main, script_parser,
                                         write_output)
from modal_spring_ros.runs.rendering import render

PROG = 'modal_spring_render'


def main(argv: list[str] | None = None) -> int:
    p = script_parser(PROG, __doc__)
    p.add_argument('run', help='bag folder, .mcap or .npz')
    p.add_argument('--output', required=True,
                   help='picture to write: .gif (an animation) or .png (snapshots)')
    p.add_argument('--topic', default='/points', help='cloud topic in bags')
    p.add_argument('--fps', type=float, default=20.0, help='animation frames a second')
    p.add_argument('--start', type=float, default=0.0, help='first time drawn, s')
    p.add_argument('--duration', type=float, default=None, help='time drawn, s (default all)')
    p.add_argument('--snapshots', type=int, default=6, help='snapshots in a .png (default 6)')
    p.add_argument('--dpi', type=int, default=80, help='resolution (default 80)')
    args = p.parse_args(argv)
    problem = _check(args)
    if problem:
        p.error(problem)

    bars = []

    def progress(done: int, total: int) -> None:   # frames drawn, with the time left
        if not bars:
            bars.append(progress_bar(PROG, total, 'frames', 'drawn'))
        bars[0](done)

    def body() -> int:
        with claimed_outputs({'--output': args.output}, {'the run': args.run}):
            run = load_run(args.run, args.topic)
            count = 0

            def draw() -> None:
                nonlocal count
                count = render(run, args.output, fps=args.fps, start=args.start,
                               duration=args.duration, snapshots=args.snapshots,
                               dpi=args.dpi, progress=progress)
            write_output(args.output, '--output', draw)
        print(f'wrote {args.output} ({count} frames of {run.name})')
        return 0

    return run_main(PROG, body)


def _check(args) -> str | None:
    for name in ('fps', 'start', 'duration'):
        value = getattr(args, name)
        if value is not None and not (math.isfinite(value) and value >= 0.0):
            return f'--{name} must be a finite number, at least 0'
    if args.fps <= 0.0 or args.fps > 100.0:
        return '--fps must be more than 0 and at most 100'
    if args.duration is not None and args.duration <= 0.0:
        return '--duration must be positive'
    if not 1 <= args.snapshots <= 24:
        return '--snapshots must be 1 to 24'
    if not 20 <= args.dpi <= 300:
        return '--dpi must be 20 to 300'
    return None


if __name__ == '__main__':
    sys.exit(main())

"""
``modal_spring_bench``: the project's benchmarks, as suites, with their results on disk.

    modal_spring_bench [--suite steps,stream,tradeoff,promise,promise_demanding,auto,response,
                                scale,headline,peer,contact,meshes,storm,watch]
                       [--quick]
                       [--case TEXT]
                       [--seeds LIST]
                       [--out DIR]

Suites: ``steps`` (median time per step, basis cost, peak memory), ``stream`` (the node's
publish rate and end-to-end latency, seen from another process), ``tradeoff`` (error against
cost of every method, stability limits, the paper's figs. 7 and 8, the large-deformation
failure, with CSV and PNG charts), ``promise`` (``modal.auto`` on 50 random scenes at 1 % and
0.3 %: measured against printed error, and its cost against the full run's, with CSV and a PNG
chart), ``promise_demanding`` (the same on 7 random scenes users bring: solids and shells from
mesh files, sheets of 5,000-7,000 particles, clamps turning +-90 degrees, 20-40 s runs; the
error in every 0.25 s window too), ``auto`` (``modal.auto`` on the built-in scenes: the plan as
predicted against the plan measured, error and cost, with CSV), ``response`` (the filter's
gains and damping requested against measured, mode by mode, with CSV and a PNG chart),
``scale`` (sheets of 10k to 500k particles: the memory estimate against the measured peak,
set-up, step and frame, and the sizes that stream at 60 Hz, with CSV and a PNG chart),
``headline`` (the README's figures over whole runs of 1 s and 5 s: the cost at 1 % error of
``--auto`` and of sampled springs against the full run's, with CSV), ``peer`` (the resonance
scenes at 1 % against Newton's semi-implicit run, an optional peer: error and CPU per simulated
second of each, with CSV and a PNG chart), ``contact`` (a sheet lowered onto a sphere and onto a
table at 1 %: the project's runs and Newton's semi-implicit run with its particle-shape contact,
error and CPU per simulated second, and what contact costs a modal run, with CSV and a PNG
chart), ``meshes`` (a 10,000-vertex cloth and a
10,000-particle solid brought as mesh files: load and precompute time with progress, the modal
step and frame against the full run's, cost per simulated second), ``storm`` (four clients
sending parameter requests without pause for 10 minutes: answer times, requests unanswered, the
node's memory over the storm, with a PNG chart), ``watch`` (a plan whose motion outgrows what
was measured, watched never due: the sentinel's windows, the fallback, the plan's error each
quarter second unwatched, with CSV and a PNG chart). Results are printed as tables and written to
``DIR/<suite>.json``. Progress goes to stderr.
"""
from __future__ import annotations

import json
import os
from pathlib import Path
import signal
import sys

from modal_spring_ros.bench.accuracy import auto_scenes
from modal_spring_ros.bench.accuracy import headline
from modal_spring_ros.bench.accuracy import promise
from modal_spring_ros.bench.accuracy import promise_demanding
from modal_spring_ros.bench.accuracy import response
from modal_spring_ros.bench.accuracy import tradeoff
from modal_spring_ros.bench.accuracy import watched
from modal_spring_ros.bench.costs import memory
from modal_spring_ros.bench.costs import meshes
from modal_spring_ros.bench.costs import steps
from modal_spring_ros.bench.costs import storm
from modal_spring_ros.bench.costs import stream
from modal_spring_ros.bench.peers import contact_drop
from modal_spring_ros.bench.peers import peer
from modal_spring_ros.cli.common import fail, progress_lines, script_parser
from modal_spring_ros.core.threads import process_threads

PROG = 'modal_spring_bench'
#: suite name -> module with run(quick, progress), table(results), write_outputs(...)
SUITES = {'steps': steps, 'stream': stream, 'tradeoff': tradeoff, 'promise': promise,
          'promise_demanding': promise_demanding,
          'auto': auto_scenes, 'response': response, 'scale': memory,
          'headline': headline, 'peer': peer, 'contact': contact_drop, 'meshes': meshes,
          'storm': storm, 'watch': watched}


def main(argv: list[str] | None = None) -> int:
    p = script_parser(PROG, __doc__)
    p.add_argument('--suite', default='steps',
                   help=f"comma-separated suites: {', '.join(SUITES)} (default steps)")
    p.add_argument('--quick', action='store_true', help='fewer repetitions and cases')
    p.add_argument('--case', default=None, metavar='TEXT',
                   help="stream suite: only the cases whose label contains TEXT (e.g. '100k')")
    p.add_argument('--seeds', default=None, metavar='LIST',
                   help="promise_demanding suite: only these seeds (e.g. '1-6' or '1,3,5'; "
                        'default all)')
    p.add_argument('--out', default=None, help='folder for the JSON results')
    args = p.parse_args(argv)
    suites = [s.strip() for s in args.suite.split(',') if s.strip()]
    unknown = [s for s in suites if s not in SUITES]
    if unknown or not suites:
        fail(PROG, f"--suite: unknown {', '.join(unknown) or '(none)'} "
                   f"(choose from {', '.join(SUITES)})")
    if 'stream' in suites:
        try:
            stream.domain_id()
        except ValueError as exc:
            fail(PROG, str(exc))
    if args.case is not None:
        if suites != ['stream']:
            fail(PROG, '--case picks stream cases: use it with --suite stream alone')
        try:
            stream.select_cases(args.case, args.quick)
        except ValueError as exc:
            fail(PROG, str(exc))
    seeds = None
    if args.seeds is not None:
        if suites != ['promise_demanding']:
            fail(PROG, '--seeds picks promise_demanding seeds: use it with that suite alone')
        try:
            seeds = promise_demanding.select_seeds(args.seeds)
        except ValueError as exc:
            fail(PROG, f'--seeds: {exc}')
    out = Path(args.out) if args.out else None
    if out is not None:
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            fail(PROG, f'--out {out}: cannot create: {exc.strerror or exc}')

    progress = progress_lines(PROG)     # a suite's counted jobs with the time they have left

    # a suite's worker processes end with it: SIGTERM unwinds as Ctrl-C does (a pool's exit
    # terminates its workers), where it would leave them running
    signal.signal(signal.SIGTERM, lambda signum, frame: sys.exit(128 + signum))

    with process_threads(os.environ):     # one BLAS thread, as the processes it measures
        for name in suites:
            module = SUITES[name]
            results = (module.run(args.quick, progress, args.case) if args.case is not None
                       else module.run(args.quick, progress, seeds) if seeds is not None
                       else module.run(args.quick, progress))
            print(f'== {name} ==')
            print(module.table(results))
            if out is not None:
                (out / f'{name}.json').write_text(json.dumps(results, indent=1, default=float))
                module.write_outputs(results, out, progress)
    return 0


if __name__ == '__main__':
    sys.exit(main())

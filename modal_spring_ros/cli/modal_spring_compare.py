"""
``modal_spring_compare``: compare two runs of one scene (bags or ``.npz``), frame by frame.

    modal_spring_compare A B [--plot out.png] [--json out.json] [--topic /points]
"""
from __future__ import annotations

import json
from pathlib import Path
import sys

from modal_spring_ros.bags.files.run_loading import load_run
from modal_spring_ros.cli.common import claimed_outputs, run_main, script_parser, write_output
from modal_spring_ros.runs.comparison import compare, plot

PROG = 'modal_spring_compare'


def main(argv: list[str] | None = None) -> int:
    p = script_parser(PROG, __doc__)
    p.add_argument('a', help='run A: bag folder, .mcap or .npz')
    p.add_argument('b', help='run B (the reference): bag folder, .mcap or .npz')
    p.add_argument('--plot', default=None, help='write a PNG: error over time and spectra')
    p.add_argument('--json', default=None, help='write every figure as JSON')
    p.add_argument('--topic', default='/points', help='cloud topic in bags')
    args = p.parse_args(argv)

    def body() -> int:
        with claimed_outputs({'--plot': args.plot, '--json': args.json},
                             {'run A': args.a, 'run B': args.b, '--plot': args.plot}):
            return report(compare(load_run(args.a, args.topic), load_run(args.b, args.topic)))

    def report(result: dict) -> int:
        print(f"{result['common_frames']} common frames of {result['a']['frames']} and "
              f"{result['b']['frames']}")
        print(f"RMS difference      {result['rms_m']:.4g} m")
        print(f"largest difference  {result['max_m']:.4g} m")
        print(f"relative L2 error   mean {result['rel_l2_mean']:.4g}, "
              f"max {result['rel_l2_max']:.4g} (against B's displacement)")
        energies = [f for f in result['per_frame'] if 'energy_a_J' in f and 'energy_b_J' in f]
        if energies:
            last = energies[-1]
            print(f"energy at the end   A {last['energy_a_J']:.6g} J, "
                  f"B {last['energy_b_J']:.6g} J")
        if args.json:
            write_output(args.json, '--json',
                         lambda: Path(args.json).write_text(json.dumps(result, indent=1)))
            print(f'wrote {args.json}')
        if args.plot:
            write_output(args.plot, '--plot', lambda: plot(result, args.plot))
            print(f'wrote {args.plot}')
        return 0

    return run_main(PROG, body)


if __name__ == '__main__':
    sys.exit(main())

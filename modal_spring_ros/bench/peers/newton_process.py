"""
Newton as a whole process, for whole-process comparisons with ``modal_spring_sim``.

    python -m modal_spring_ros.bench.peers.newton_process SCENE --duration S --dt DT

Loads ``SCENE`` (a built-in name or a scene file), builds it in Newton
(:class:`~modal_spring_ros.bench.peers.newton_peer.NewtonRun`: Warp's kernels compiled or taken
from Warp's cache, two steps captured as a graph) and steps it for ``S`` simulated seconds at
``DT`` (the step the peer suite found to meet the tolerance), as a Newton user's script does;
then prints the steps taken and the largest displacement. Its CPU time as a whole process
(``/usr/bin/time -v``) is what a user of Newton pays for the same run.
"""
from __future__ import annotations

import argparse
import sys

from modal_spring_ros.bench.peers.newton_peer import NewtonRun
from modal_spring_ros.scenes.resources import load_scene
import numpy as np

#: steps per call while running (the run's frames)
CHUNK = 1000


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog='newton_process', description=__doc__.split('\n')[1])
    p.add_argument('scene')
    p.add_argument('--duration', type=float, required=True)
    p.add_argument('--dt', type=float, required=True)
    args = p.parse_args(argv)
    run = NewtonRun(load_scene(args.scene), args.dt)
    steps = int(round(args.duration / args.dt))
    for start in range(0, steps, CHUNK):
        run.step(min(CHUNK, steps - start))
    largest = float(np.abs(run.displacement()).max())
    print(f'{run.steps} steps of {args.dt:g} s: {run.time:.3f} s; largest displacement '
          f'{largest:.4g} m')
    return 0


if __name__ == '__main__':
    sys.exit(main())

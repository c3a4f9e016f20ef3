"""
What a run costs a user as a whole process: ``modal_spring_sim`` run on a scene, its CPU time.

A user pays the process: the interpreter, the imports, loading the scene, planning and the run.
Measured in-process, planning's fixed part (tens of milliseconds) looks large beside the full
run of a small scene over 3 s (hundreds of milliseconds less than the process around it).
:func:`process_costs` writes the scene to a file and runs ``modal_spring_sim`` on it with
``--auto`` at the tolerance and with ``--method full`` (its default step), each in a process of
its own, one BLAS thread, a modes cache of its own; their CPU time (user and system, the
process and whatever it waited for) is what each costs: the median of ``REPEATS`` runs of each,
taken in turn (a process of under a second, run once beside a benchmark's other worker, was
a third off the median of five of the same: three scenes seemed to cost 1.23-1.43 times the
full run that cost 0.93-1.04 times it).
"""
from __future__ import annotations

import os
from pathlib import Path
import resource
import statistics
import subprocess
import sys
import tempfile

from modal_spring_ros.core.model.scene import Scene
from modal_spring_ros.runs.sample_cache import CACHE_ENV
from modal_spring_ros.scenes.files.writing import scene_to_yaml

#: the command, run by this interpreter (the package's console script, as a module)
COMMAND = (sys.executable, '-m', 'modal_spring_ros.cli.modal_spring_sim')
#: a run that takes longer is reported as failed, s
TIMEOUT_S = 1800.0
#: runs of each process whose median is its cost
REPEATS = 3


def process_env(folder: Path) -> dict[str, str]:
    """
    Return the environment a measured process runs in: one BLAS thread, a cache in ``folder``.

    A cache of its own: nothing another run left is read.
    """
    env = dict(os.environ, OPENBLAS_NUM_THREADS='1', OMP_NUM_THREADS='1', MKL_NUM_THREADS='1')
    env[CACHE_ENV] = str(Path(folder) / 'cache')
    return env


def cpu_seconds(command: list[str], env: dict[str, str]) -> float:
    """
    Return the CPU seconds ``command`` took as a process (raises where it failed).

    Read from the children's resource usage before and after: the process is waited for, so its
    own time and its children's are there.
    """
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    done = subprocess.run(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                          text=True, timeout=TIMEOUT_S)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise RuntimeError(f'{" ".join(command)} exited with {done.returncode}: '
                           f'{done.stderr.strip()[-300:]}')
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def cli_cpu_seconds(args: list[str], env: dict[str, str]) -> float:
    """Return the CPU seconds ``modal_spring_sim args`` took as a process (:func:`cpu_seconds`)."""
    return cpu_seconds([*COMMAND, *args], env)


def process_costs(scene: Scene, tolerance: float, duration_s: float) -> tuple[float, float]:
    """
    Return the CPU seconds of ``--auto`` at ``tolerance`` and of ``--method full``, as processes.

    Both over ``duration_s`` on ``scene`` (written to a scene file), quiet, no output written;
    each the median of ``REPEATS`` runs, the two in turn, every run with a cache of its own
    (nothing an earlier run solved is read).
    """
    with tempfile.TemporaryDirectory(prefix='cli_runs_') as folder:
        path = Path(folder) / f'{scene.name}.yaml'
        path.write_text(scene_to_yaml(scene))
        common = ['--scene', str(path), '--duration', repr(float(duration_s)), '--quiet']
        runs = {'auto': ['--auto', '--tolerance', repr(float(tolerance))],
                'full': ['--method', 'full']}
        costs: dict[str, list[float]] = {name: [] for name in runs}
        for k in range(REPEATS):
            for name, args in runs.items():
                env = process_env(Path(folder) / f'{name}_{k}')
                costs[name].append(cli_cpu_seconds([*common, *args], env))
    return statistics.median(costs['auto']), statistics.median(costs['full'])

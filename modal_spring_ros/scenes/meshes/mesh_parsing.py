"""
A mesh file parsed in an interpreter of its own, within a memory limit and a CPU limit.

``python -m modal_spring_ros.scenes.meshes.mesh_parsing PATH MAX_BYTES BUDGET CPU_S`` limits
its address space to what it maps now plus ``BUDGET`` bytes and its CPU time to ``CPU_S``
seconds (a file that sends a parser into a loop ends there), parses ``PATH``
(:func:`~modal_spring_ros.scenes.meshes.mesh_files.parse_mesh`; the mesh and the files it
refers to within ``MAX_BYTES``), and writes the arrays to stdout as an ``.npz`` archive. A
refusal is one line on stderr and exit status 2; an allocation beyond the limit is such a
refusal. :func:`~modal_spring_ros.scenes.meshes.mesh_files.read_mesh` runs it.
"""
from __future__ import annotations

import io
import os
from pathlib import Path
import resource
import sys

from modal_spring_ros.core.model.scene import SceneError
from modal_spring_ros.scenes.meshes.mesh_files import parse_mesh, PARSE_REFUSED
import numpy as np


def limit_memory(budget: int) -> None:
    """Let this process map at most ``budget`` bytes more than it maps now."""
    with open('/proc/self/statm') as fh:
        mapped = int(fh.read().split()[0]) * os.sysconf('SC_PAGE_SIZE')
    _, hard = resource.getrlimit(resource.RLIMIT_AS)
    cap = mapped + budget
    resource.setrlimit(resource.RLIMIT_AS, (cap if hard == resource.RLIM_INFINITY
                                            else min(cap, hard), hard))


def limit_cpu(seconds: int) -> None:
    """Let this process use at most ``seconds`` of CPU in all (then SIGXCPU ends it)."""
    _, hard = resource.getrlimit(resource.RLIMIT_CPU)
    if hard != resource.RLIM_INFINITY:
        seconds = min(seconds, hard)
    resource.setrlimit(resource.RLIMIT_CPU, (seconds, hard))


def main(argv: list[str]) -> int:
    path, max_bytes, budget, cpu_s = Path(argv[0]), int(argv[1]), int(argv[2]), int(argv[3])
    limit_memory(budget)
    limit_cpu(cpu_s)
    try:
        vertices, triangles, tetrahedra = parse_mesh(path, max_bytes)
        out = io.BytesIO()
        np.savez(out, vertices=vertices, triangles=triangles, tetrahedra=tetrahedra)
    except SceneError as exc:
        print(str(exc).replace('\n', ' '), file=sys.stderr)
        return PARSE_REFUSED
    except MemoryError:
        print(f'{path}: reading the mesh needs more than the {budget / 2**20:.0f} MiB it may '
              'take (a damaged or hostile file, or too large a mesh for this machine)',
              file=sys.stderr)
        return PARSE_REFUSED
    sys.stdout.buffer.write(out.getvalue())
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))

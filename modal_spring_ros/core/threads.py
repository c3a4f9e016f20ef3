"""
How many threads the BLAS library may use: per-step linear algebra runs on one.

numpy and scipy call a multithreaded BLAS (OpenBLAS), which by default uses every core for every
product. Measured on a 2-core machine, one product of a (rows x columns) matrix with a vector:

=================  ===============  ==================================
multiply-adds      2 threads, quiet  2 threads, two busy processes beside
=================  ===============  ==================================
48,000             1.0x              1.4x faster
0.5 - 1 million    1.9 - 2.0x        3 - 11x slower
2 - 7 million      1.6 - 2.8x        1.3x faster to 3x slower
=================  ===============  ==================================

The gain on a quiet machine is at most the core count; the loss on a busy one (the threads wait
for each other on cores others hold) is up to ten times, and the waiting threads burn CPU the
run does not use. A node shares its machine with a robot, so everything that runs per step or
per frame (the step, the forces, the positions of a frame, and the spring sample's training,
which is many small products) runs on one thread, and so does the node's worker process (its
mode computation gained 0-25 % of wall time on two threads for 30-75 % more CPU,
:mod:`~modal_spring_ros.core.worker`). One-off work in a process of its own (the mode
computation of ``modal_spring_sim``) keeps the library's default.

The limit is process-wide (it is the library's setting): :func:`stepping_threads` counts its
holders, so the simulation thread, a training in another thread and a benchmark may nest and
overlap, and the library's own setting comes back when the last one leaves. (OpenBLAS lets a
thread raise the count only in some cases: if the last to leave is not the thread that entered
first, the process may stay at one thread. The front ends hold it for their whole run, so this
does not arise there.)
"""
from __future__ import annotations

import contextlib
import threading
from typing import Iterator

from threadpoolctl import ThreadpoolController

#: BLAS threads for per-step and per-frame work
STEP_THREADS = 1

_lock = threading.Lock()
_holders = 0
_limit = None          # the active limit (threadpoolctl's; restores the previous setting)
_controller: ThreadpoolController | None = None


@contextlib.contextmanager
def stepping_threads() -> Iterator[None]:
    """Run the body with BLAS on :data:`STEP_THREADS` thread(s), process-wide, nestable."""
    global _holders, _limit, _controller
    with _lock:
        if _holders == 0:
            if _controller is None:    # finds the loaded BLAS libraries once (about 1 ms)
                _controller = ThreadpoolController()
            _limit = _controller.limit(limits=STEP_THREADS, user_api='blas')
        _holders += 1
    try:
        yield
    finally:
        with _lock:
            _holders -= 1
            if _holders == 0:
                _limit.restore_original_limits()
                _limit = None


def blas_threads() -> int:
    """Return the number of threads the loaded BLAS libraries use now (the largest)."""
    info = ThreadpoolController().select(user_api='blas').info()
    return max((lib['num_threads'] for lib in info), default=1)

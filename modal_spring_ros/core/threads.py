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
:mod:`~modal_spring_ros.core.worker`).

A user pays a run's CPU, so the console scripts run their one-off work (a scene's modes, their
derivatives, planning) on one thread too, for the whole process (:func:`process_threads`),
unless their environment names a count (``OPENBLAS_NUM_THREADS`` and the like: a user who wants
the wall time of more cores asks for them so). Measured whole processes of ``modal_spring_sim``
on the 2-core machine, the library's default of two threads against one (medians of 3): the
cloth swung into a sphere over 5 s, 12 % more CPU and 4 % more wall time under ``--auto`` (its
modes, derivatives and planning); a 14^3 block's 256 modes (7,644 DOF) and 0.5 s of its modal
run, 1.5 times the CPU for 13 % less wall time.

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
from typing import Iterator, Mapping

from threadpoolctl import ThreadpoolController

#: BLAS threads for per-step and per-frame work
STEP_THREADS = 1
#: The environment variables that set the BLAS library's threads (OpenBLAS, OpenMP, MKL)
THREAD_VARIABLES = ('OPENBLAS_NUM_THREADS', 'OMP_NUM_THREADS', 'MKL_NUM_THREADS')

_lock = threading.Lock()
_holders = 0
_saved: list[tuple[object, int]] = []      # each BLAS library and its count before the first
_controller: ThreadpoolController | None = None


class stepping_threads(contextlib.ContextDecorator):   # noqa: N801 (used as a function is)
    """
    Run the body with BLAS on :data:`STEP_THREADS` thread(s), process-wide, nestable.

    A context manager and a decorator. Each library's count is read and set through
    threadpoolctl's controller of it (a call into the library), not through a limiter (which
    reads every library's full description: 16 us, paid on every step by a caller that steps
    one at a time, against 8 us now), and a library already at the count is left alone.
    """

    def __enter__(self) -> None:
        global _holders, _saved, _controller
        with _lock:
            if _holders == 0:
                if _controller is None:    # finds the loaded BLAS libraries once (about 1 ms)
                    _controller = ThreadpoolController().select(user_api='blas')
                _saved = [(lib, count) for lib in _controller.lib_controllers
                          if (count := lib.get_num_threads()) not in (None, STEP_THREADS)]
                for lib, _ in _saved:
                    lib.set_num_threads(STEP_THREADS)
            _holders += 1

    def __exit__(self, *exc) -> None:
        global _holders, _saved
        with _lock:
            _holders -= 1
            if _holders == 0:
                for lib, count in _saved:
                    lib.set_num_threads(count)
                _saved = []


def threads_set_by(env: Mapping[str, str]) -> str | None:
    """Return the variable of ``env`` that sets the BLAS library's threads (None: none does)."""
    return next((name for name in THREAD_VARIABLES if env.get(name, '').strip()), None)


@contextlib.contextmanager
def process_threads(env: Mapping[str, str]) -> Iterator[None]:
    """
    Run a console script's body with BLAS on :data:`STEP_THREADS` thread(s), process-wide.

    Unless ``env`` (the script's environment) sets the count: the library then keeps the
    user's (per-step work still runs on one, :func:`stepping_threads`).
    """
    if threads_set_by(env):
        yield
        return
    with stepping_threads():
        yield


def blas_threads() -> int:
    """Return the number of threads the loaded BLAS libraries use now (the largest)."""
    info = ThreadpoolController().select(user_api='blas').info()
    return max((lib['num_threads'] for lib in info), default=1)

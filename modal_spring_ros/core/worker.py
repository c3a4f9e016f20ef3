"""
A child process that runs long numerical calls, so that the caller's interpreter stays free.

scipy's Lanczos eigensolver holds the interpreter lock for tens to hundreds of milliseconds at
a time (its restarts and the final Ritz vectors run without releasing it). In a process that
also streams frames, every such hold is a late frame. :class:`WorkerProcess` runs those calls
in one long-lived child process instead; the calling thread only waits on a pipe, so the other
threads of the caller keep running.

The child is started (``spawn``) on the first call and reused, so state a call leaves in the
child (a sparse factorisation, say) is there for the next one. It ignores SIGINT and SIGTERM:
Ctrl-C reaches the whole process group from a terminal, and ``timeout`` or a service manager
signal the whole group too; the parent decides when the child ends (and ends it with SIGKILL:
it holds nothing that needs cleaning up).

Its calls run with one BLAS thread and a lower priority: it works beside a stream on the same
machine. Measured on a 2-core machine, ``sheet_316x316``'s 32 modes took 20.3 s of CPU (and of
wall time) on one thread, and 26-35 s of CPU for 15-22 s of wall time on two.
"""
from __future__ import annotations

import multiprocessing as mp
from multiprocessing.connection import Connection
import os
import signal
import threading
from typing import Any, Callable

from threadpoolctl import threadpool_limits

#: How often a waiting call asks whether it was cancelled, s.
POLL_S = 0.1
#: How much lower the child's priority is than its parent's once the parent streams
#: (:meth:`WorkerProcess.give_way`): its long computations then give way to the stream, which
#: shares no lock with them. Before that (a node's first modes, nothing streamed yet) it runs
#: at the parent's priority: a user waits for it, and no stream does.
WORKER_NICENESS = 10
#: The lowest priority there is (the highest niceness).
MAX_NICENESS = 19
#: BLAS threads of the child's calls
WORKER_THREADS = 1
#: the signals the child ignores (its parent ends it)
IGNORED_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class WorkerError(RuntimeError):
    """
    A call got no answer.

    The worker was closed or the call cancelled, or the child died (killed, out of memory, ...).
    """


def _serve(conn: Connection, niceness: int) -> None:
    """
    Child's main loop, ``niceness`` below its parent's priority.

    Answer ``(function, args)`` with ``(True, result)`` or ``(False, exception)`` until the pipe
    closes.
    """
    for number in IGNORED_SIGNALS:
        signal.signal(number, signal.SIG_IGN)
    if niceness:
        _lower(0, niceness)
    while True:
        try:
            function, args = conn.recv()
        except (EOFError, OSError):
            return
        try:
            # the libraries loaded by now (unpickling the call imports its modules): limited
            with threadpool_limits(limits=WORKER_THREADS, user_api='blas'):
                answer = (True, function(*args))
        except Exception as exc:  # handed back to the caller, raised there
            answer = (False, exc)
        conn.send(answer)


def _lower(pid: int, niceness: int) -> None:
    """Set process ``pid``'s priority (0: this one) ``niceness`` below this process's own."""
    try:
        own = os.getpriority(os.PRIO_PROCESS, 0)
        os.setpriority(os.PRIO_PROCESS, pid, min(own + niceness, MAX_NICENESS))
    except OSError:     # gone, or the system refuses: it keeps the priority it has
        pass


def _end(process: mp.process.BaseProcess) -> None:
    process.kill()
    process.join(timeout=5.0)


def _ended(code: int | None) -> str:
    """Say how a child that answered nothing ended, from its exit code."""
    if code is None or code >= 0:
        return f'exit code {code}'
    if -code == signal.SIGKILL:
        return 'killed (SIGKILL: out of memory?)'
    try:
        return f'killed by {signal.Signals(-code).name}'
    except ValueError:
        return f'killed by signal {-code}'


class WorkerProcess:
    """
    Calls module-level functions in a child process, one call at a time.

    Thread-safe: concurrent callers are served one after the other. ``cancelled``, when
    given, is asked every :data:`POLL_S` while a call runs; once it answers True the child is
    ended and the call raises :class:`WorkerError` (a node passes "its context is shut down",
    so that Ctrl-C does not wait for a long computation). :meth:`close` ends the child, and a
    call in progress raises :class:`WorkerError` in its caller. The child runs at the parent's
    priority until :meth:`give_way` (a node: once it streams), then ``WORKER_NICENESS`` below it.
    """

    def __init__(self, name: str = 'modal_spring_worker',
                 cancelled: Callable[[], bool] | None = None):
        self.name = name
        self.cancelled = cancelled
        self._process: mp.process.BaseProcess | None = None
        self._conn: Connection | None = None
        self._lock = threading.Lock()
        self._closed = False
        self._niceness = 0

    def call(self, function: Callable[..., Any], *args: Any) -> Any:
        """``function(*args)`` evaluated in the child; its exception is raised here."""
        with self._lock:
            if self._closed:
                raise WorkerError(f'{self.name} is closed')
            if self._process is None or not self._process.is_alive():
                self._start()
            process, conn = self._process, self._conn
            try:
                conn.send((function, args))
                while not conn.poll(POLL_S):
                    if self.cancelled is not None and self.cancelled():
                        raise WorkerError(f'{self.name}: call cancelled')
                ok, value = conn.recv()
            except (EOFError, OSError):
                process.join(timeout=1.0)
                self._forget(process)
                code = process.exitcode
                cause = 'closed' if self._closed else _ended(code)
                raise WorkerError(f'{self.name} ended during the call ({cause})') from None
            except BaseException:  # cancelled or interrupted: its answer would come unasked
                _end(process)
                self._forget(process)
                raise
        if ok:
            return value
        raise value

    def give_way(self) -> None:
        """
        Lower the child's priority (``WORKER_NICENESS`` below this process's) from now on.

        A caller that streams calls it once the stream runs: the long computations it asks for
        then give way to the stream on a busy machine; before, nothing streams and a user waits
        for them. One way: a process may lower its child's priority, not raise it again; a
        child started later starts lowered.
        """
        self._niceness = WORKER_NICENESS
        process = self._process
        if process is not None and process.pid is not None:
            _lower(process.pid, WORKER_NICENESS)

    def close(self) -> None:
        """End the child now; a call in progress raises :class:`WorkerError` in its caller."""
        self._closed = True
        process, conn = self._process, self._conn
        if process is not None:
            _end(process)
        if conn is not None and not self._lock.locked():
            conn.close()

    def _forget(self, process: mp.process.BaseProcess) -> None:
        if self._process is process:
            self._process = self._conn = None

    def __enter__(self) -> 'WorkerProcess':
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _start(self) -> None:
        ctx = mp.get_context('spawn')
        parent, child = ctx.Pipe()
        process = ctx.Process(target=_serve, args=(child, self._niceness), name=self.name,
                              daemon=True)
        process.start()
        child.close()
        self._process, self._conn = process, parent

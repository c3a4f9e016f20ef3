"""
Benchmark cases in other processes (``spawn``), their end always known.

:func:`in_child` calls a function in a fresh process (its peak memory its own) and returns what
it returns. A child that raises gives a :class:`ChildFailed` naming the exception; one that
ends without an answer (killed, out of memory, its stderr gone) gives one saying how it ended:
the benchmark stops with a reason, it never waits on a queue no one will write to again.
:func:`pooled` hands jobs to a pool of processes the same way: a pool replaces a worker that
died and drops its job, which would leave the caller waiting for it forever.
"""
from __future__ import annotations

import multiprocessing as mp
import queue as queues
import signal
from typing import Any, Callable, Iterator

#: how often a wait for the child checks that it still runs, s
POLL_S = 0.2
#: how long a child that answered has to end before it is killed, s
END_S = 30.0


class ChildFailed(RuntimeError):
    """A case's process raised, or ended without an answer."""


def _report(channel, message: str) -> None:
    channel.put(('progress', message))


def _serve(channel, function: Callable, args: tuple, reporting: bool) -> None:
    try:
        progress = (lambda message: _report(channel, message)) if reporting else None
        answer = function(*args, progress) if reporting else function(*args)
        channel.put(('result', answer))
    except Exception as exc:        # handed to the parent, which names the case
        channel.put(('error', f'{type(exc).__name__}: {exc}'))


def how_it_ended(exitcode: int | None) -> str:
    """Return a process's exit code in words."""
    if exitcode is not None and exitcode < 0:
        name = signal.Signals(-exitcode).name
        return f'killed by {name}' + (' (out of memory?)' if name == 'SIGKILL' else '')
    return f'exit status {exitcode}'


def in_child(function: Callable, *args: Any, what: str = 'the case',
             progress: Callable[[str], None] | None = None) -> Any:
    """
    Return ``function(*args)`` computed in a fresh process.

    With ``progress``, ``function`` is called with one more argument, a callable whose messages
    reach ``progress`` here as they come. ``what`` names the case in a failure.

    :raises ChildFailed: the function raised, or its process ended without an answer.
    """
    context = mp.get_context('spawn')
    channel = context.Queue()
    child = context.Process(target=_serve, args=(channel, function, args, progress is not None))
    child.start()
    try:
        while True:
            ended = not child.is_alive()    # then all it sent is in the queue already
            try:
                kind, value = channel.get(timeout=POLL_S)
            except queues.Empty:
                if ended:
                    raise ChildFailed(f'{what}: its process ended without an answer '
                                      f'({how_it_ended(child.exitcode)})') from None
                continue
            if kind == 'progress':
                progress(value)
            elif kind == 'error':
                raise ChildFailed(f'{what}: {value}')
            else:
                return value
    finally:
        child.join(END_S)
        if child.is_alive():
            child.kill()
            child.join()
        channel.close()


def pooled(pool: mp.pool.Pool, function: Callable, jobs: list, what: str) -> Iterator:
    """
    Yield ``function(job)`` for each of ``jobs`` from ``pool``, as each is done.

    :raises ChildFailed: one of the pool's processes ended (its job is lost with it).
    """
    workers = {child.pid for child in mp.active_children()}
    answers = pool.imap_unordered(function, jobs)
    for _ in jobs:
        while True:
            try:
                yield answers.next(timeout=POLL_S)
                break
            except mp.TimeoutError:
                if not workers <= {child.pid for child in mp.active_children()}:
                    raise ChildFailed(f'{what}: a worker process ended without an answer '
                                      '(killed: out of memory?)') from None

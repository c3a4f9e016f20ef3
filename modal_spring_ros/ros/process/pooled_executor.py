"""
An executor that runs callbacks on a pool of threads and ends with none of them in flight.

rclpy's ``MultiThreadedExecutor`` (Jazzy) hands a ready callback to a thread pool and looks at its
outcome only on a later ``spin_once``; its ``shutdown`` neither waits for callbacks that are
running nor for those queued in the pool, and destroys the guard condition they trigger first.
After the spin loop ends, a queued callback then fails in a pool thread (``InvalidHandle``: "cannot
use Destroyable because destruction was requested"), the failure is printed at some later garbage
collection ("The following exception was never retrieved"), and a running one may still be inside
the middleware while the node and the context are destroyed under it.

:class:`PooledExecutor` keeps what it handed to its threads: on ``shutdown`` the callbacks
already handed over (queued or running) run to their end while what they use still exists; any
failure is reported, and only then does rclpy destroy the rest. It uses the public
``Executor.wait_for_ready_callbacks`` only.
"""
from __future__ import annotations

import concurrent.futures
import threading

from rclpy.executors import (ConditionReachedException, Executor, ExternalShutdownException,
                             ShutdownException, TimeoutException)
from rclpy.logging import get_logger
from rclpy.task import Future

#: what a stop waits at most for callbacks that are running, s
DRAIN_TIMEOUT_S = 10.0
#: longest wait for a pool thread to start a callback handed over, s
HANDOFF_WAIT_S = 0.05


class PooledExecutor(Executor):
    """Run callbacks on ``num_threads`` threads; :meth:`shutdown` leaves none of them running."""

    def __init__(self, num_threads: int, *, context=None, name: str = 'executor'):
        super().__init__(context=context)
        self._pool = concurrent.futures.ThreadPoolExecutor(num_threads,
                                                           thread_name_prefix=name)
        self._logger = get_logger(name)
        # (handler, its pool call, set once a pool thread has started it)
        self._handed: list[tuple[object, concurrent.futures.Future, threading.Event]] = []
        self._handed_lock = threading.Lock()

    def spin_once(self, timeout_sec: float | None = None) -> None:
        """Hand one ready callback to the pool; raise what a finished one raised."""
        self._spin_once_impl(timeout_sec)

    def spin_once_until_future_complete(self, future: Future,
                                        timeout_sec: float | None = None) -> None:
        """As :meth:`spin_once`, returning early once ``future`` is done."""
        future.add_done_callback(lambda _: self.wake())
        self._spin_once_impl(timeout_sec, future.done)

    def _spin_once_impl(self, timeout_sec, condition=lambda: False) -> None:
        try:
            handler, _, _ = self.wait_for_ready_callbacks(timeout_sec, None, condition)
        except (ExternalShutdownException, ShutdownException, TimeoutException,
                ConditionReachedException):
            return
        with self._handed_lock:
            queued = next((started for h, call, started in self._handed
                           if h is handler and not call.done()), None)
            if queued is None:
                started = threading.Event()
                self._handed.append((handler, self._pool.submit(_run, handler, started),
                                     started))
        if queued is not None:
            # rclpy yields a task again until a thread runs it: handing it over again would
            # spin this thread on a core (a /clock at 100 Hz under use_sim_time did, starving
            # the run of the interpreter); wait for a pool thread to start it instead
            queued.wait(HANDOFF_WAIT_S)
        for handler in self._take_finished():
            handler.result()                                # raises what the callback raised

    def _take_finished(self) -> list:
        """Remove and return the handlers whose pool call has ended."""
        with self._handed_lock:
            finished = [h for h, call, _ in self._handed if call.done()]
            self._handed = [entry for entry in self._handed if not entry[1].done()]
        return finished

    def drain(self, timeout_sec: float | None = DRAIN_TIMEOUT_S) -> bool:
        """
        Wait for the callbacks handed to the pool, queued or running.

        A queued one is not cancelled: its coroutine would be left never awaited (a warning at
        collection). Return whether none is left running; a failure is logged, not lost.
        """
        with self._handed_lock:
            running = [call for _, call, _ in self._handed]
        _, left = concurrent.futures.wait(running, timeout=timeout_sec)
        for handler in self._take_finished():
            if not handler.done():
                continue
            failure = handler.exception()                   # fetched: not printed at collection
            if failure is not None:
                self._logger.error(f'a callback failed while stopping: {failure!r}')
        if left:
            self._logger.warning(f'{len(left)} callback(s) still running after '
                                 f'{timeout_sec} s; stopping anyway')
        return not left

    def shutdown(self, timeout_sec: float | None = None) -> bool:
        """Drain (within ``timeout_sec``, or :data:`DRAIN_TIMEOUT_S`), then shut rclpy's side."""
        drained = self.drain(DRAIN_TIMEOUT_S if timeout_sec is None else timeout_sec)
        finished = super().shutdown(timeout_sec)
        self._pool.shutdown(wait=drained, cancel_futures=True)
        return drained and finished


def _run(handler, started: threading.Event) -> None:
    """Run ``handler`` in a pool thread, saying first that it has started."""
    started.set()
    handler()

"""
Ctrl-C and SIGTERM as a request to stop, so ROS is shut down only once nothing waits on it.

rclpy's own handlers shut the ROS context down from the signal, at any moment: a thread of the
process that is inside a wait at that instant (the node's input companion, its executor's
threads) then reads entities that the shutdown and the stop that follows are tearing down, which
crashed the node at exit (a segmentation fault in ``EventHandler.is_ready``; rclpy issue 760 is
the same race). With :class:`StopSignals` installed instead, a signal only asks the process to
stop: the spin loop returns, the node stops and joins its own threads while ROS is still up, and
ROS is shut down last (:func:`init_ros`). Before the node streams, a signal interrupts at once
(``KeyboardInterrupt``: a long mode computation is not sat through); a second signal does so at
any time, for a stop that does not come.
"""
from __future__ import annotations

import signal
import threading

from modal_spring_ros.ros.process.pooled_executor import DRAIN_TIMEOUT_S
import rclpy
from rclpy.context import Context
from rclpy.executors import Executor
from rclpy.signals import SignalHandlerOptions

#: longest the spin loop waits for work before it checks whether it should stop, s
SPIN_SLICE_S = 0.25
#: the signals that ask the process to stop
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class StopSignals:
    """SIGINT and SIGTERM set :attr:`requested`; they interrupt while :attr:`interrupting`."""

    def __init__(self):
        #: set by the first signal
        self.requested = threading.Event()
        #: whether a first signal also raises ``KeyboardInterrupt`` (before streaming)
        self.interrupting = True

    def install(self) -> StopSignals:
        """Take SIGINT and SIGTERM (from the main thread, before :func:`init_ros`)."""
        for number in STOP_SIGNALS:
            signal.signal(number, self._on_signal)
        return self

    def _on_signal(self, _number, _frame) -> None:
        again = self.requested.is_set()
        self.requested.set()
        if self.interrupting or again:
            raise KeyboardInterrupt

    def running(self, context) -> bool:
        """Return whether the process goes on: no stop asked, and ROS still up."""
        return not self.requested.is_set() and context.ok()


def init_ros(args: list[str] | None) -> None:
    """``rclpy.init`` without rclpy's signal handlers (the caller's :class:`StopSignals`)."""
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)


def end_ros(context: Context | None = None) -> None:
    """
    Shut ROS down (if still up) and destroy its context: the middleware's participant with it.

    What a process does last, once its nodes are destroyed. The participant goes now, in order,
    while the interpreter is whole, and not among the objects the interpreter's exit collects
    (in no set order, with the middleware's threads still running: a process aborted once there,
    at its exit, after a clean stop). ``context``: the default context when None (a later
    ``rclpy.init`` in the process makes a new one, as after ``rclpy.try_shutdown``).
    """
    ended = context or rclpy.get_default_context()
    rclpy.try_shutdown(context=context)
    ended.destroy()


def spin_until_stopped(executor: Executor, stop: StopSignals | None = None) -> None:
    """
    Spin until a stop is asked or ROS is shut down, never waiting unboundedly.

    ``Executor.spin`` waits for work with no timeout and counts on a guard condition to wake it
    when ROS is shut down; when that trigger is taken by a wait that still saw the context up, the
    wait that follows never returns. Waiting in slices makes the check the thing that ends it.
    Callbacks still running are waited for (a :class:`PooledExecutor` cancels queued ones).
    """
    try:
        while (stop is None or not stop.requested.is_set()) and executor.context.ok():
            executor.spin_once(timeout_sec=SPIN_SLICE_S)
    finally:
        executor.shutdown(timeout_sec=DRAIN_TIMEOUT_S)

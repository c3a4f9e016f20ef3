"""PooledExecutor: callbacks on a pool of threads, none left in flight after a stop."""
from __future__ import annotations

import gc
import threading
import time

from modal_spring_ros.ros.process.pooled_executor import PooledExecutor
from modal_spring_ros.ros.process.stop_signals import spin_until_stopped, StopSignals
import pytest
import rclpy
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.context import Context
from ros_harness import DOMAIN_ID, wait_for
from std_msgs.msg import String


class _Ros:
    """A node in its own context with a :class:`PooledExecutor` spun as the node spins it."""

    def __init__(self, name: str):
        self.context = Context()
        rclpy.init(context=self.context, domain_id=DOMAIN_ID)
        self.node = rclpy.create_node(name, context=self.context)
        self.group = ReentrantCallbackGroup()
        self.executor = PooledExecutor(2, context=self.context, name=f'{name}_executor')
        self.executor.add_node(self.node)
        self.stop = StopSignals()
        self.thread = threading.Thread(target=spin_until_stopped,
                                       args=(self.executor, self.stop), daemon=True)

    def timer(self, period: float, callback):
        self.node.create_timer(period, callback, callback_group=self.group)

    def run_for(self, seconds: float) -> None:
        self.thread.start()
        time.sleep(seconds)
        self.stop.requested.set()
        self.thread.join(30.0)
        assert not self.thread.is_alive(), 'the spin loop did not end'

    def close(self) -> None:
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


@pytest.mark.ros
def test_stopping_under_a_flood_of_callbacks_leaves_no_failed_callback_behind(capsys):
    """
    Callbacks queued in the pool when the spin loop ends run before rclpy's guard goes.

    With rclpy's ``MultiThreadedExecutor`` this scene leaves dozens of tasks that failed with
    ``InvalidHandle`` and print "never retrieved" at a later collection, in whichever test runs.
    """
    ran = []
    for _ in range(20):
        ros = _Ros('pool_flood')
        ros.timer(0.0005, lambda: time.sleep(0.02))
        ros.timer(0.0005, lambda: time.sleep(0.02))
        ros.timer(0.0005, lambda: ran.append(1))
        ros.run_for(0.15)
        ros.close()
        del ros
        gc.collect()
    err = capsys.readouterr().err
    assert ran, 'no callback ran'
    assert 'never retrieved' not in err and 'Destroyable' not in err, err


@pytest.mark.ros
def test_a_stop_waits_for_the_callback_that_is_running():
    ros = _Ros('pool_wait')
    started, finished = threading.Event(), threading.Event()

    def slow():
        if started.is_set():
            return
        started.set()
        time.sleep(0.5)
        finished.set()
    ros.timer(0.01, slow)
    ros.thread.start()
    assert wait_for(started.is_set, 20), 'the callback never started'
    ros.stop.requested.set()
    ros.thread.join(30.0)
    assert finished.is_set(), 'the spin loop ended while a callback was still running'
    ros.close()


@pytest.mark.ros
def test_a_failing_callback_is_raised_from_the_spin_loop():
    ros = _Ros('pool_raise')

    def fail():
        raise ZeroDivisionError('in a callback')
    ros.timer(0.01, fail)
    try:
        with pytest.raises(ZeroDivisionError, match='in a callback'):
            deadline = time.monotonic() + 20
            while time.monotonic() < deadline:
                ros.executor.spin_once(timeout_sec=0.05)
    finally:
        assert ros.executor.shutdown(timeout_sec=10.0)
        ros.close()


@pytest.mark.ros
def test_a_callback_waiting_for_a_thread_is_handed_over_once_and_the_loop_does_not_spin():
    """
    A task rclpy yields again and again until a thread runs it is handed over once.

    With every pool thread busy, the next message's task waits in the pool: the spin loop must
    wait for a thread to take it, not hand it over again on every turn (under use_sim_time a
    /clock at 100 Hz kept the node's spin loop on a core that way, and its run starved).
    """
    ros = _Ros('pool_busy')
    release = threading.Event()
    got: list[str] = []
    ros.node.create_subscription(String, '/pool_busy', lambda m: (got.append(m.data),
                                                                  release.wait(10.0)), 10,
                                 callback_group=ros.group)
    handed = []
    real_submit = ros.executor._pool.submit
    ros.executor._pool.submit = lambda *args: (handed.append(args), real_submit(*args))[1]
    pub = ros.node.create_publisher(String, '/pool_busy', 10)
    try:
        ros.thread.start()
        for k in range(4):          # two fill the threads, the others wait in the pool
            pub.publish(String(data=str(k)))
            time.sleep(0.05)
        time.sleep(0.5)
        assert sorted(got) == ['0', '1'] and len(handed) <= 4, len(handed)
        release.set()
        assert wait_for(lambda: sorted(got) == ['0', '1', '2', '3'], 10)
    finally:
        release.set()
        ros.stop.requested.set()
        ros.thread.join(30.0)
        ros.close()

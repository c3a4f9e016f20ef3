"""
Ctrl-C and SIGTERM stop the node's threads first and shut ROS down last.

``modal_spring_node`` once died of a segmentation fault at exit, now and then: rclpy's signal
handler shut the context down while the input companion's thread waited on it. The signals now
only ask for a stop; these tests hold the order (stop asked, threads joined with ROS up, ROS
shut down last) in this process, with real signals.
"""
from __future__ import annotations

import os
import signal
import threading
import time

from modal_spring_ros.ros.node import ModalSpringNode
from modal_spring_ros.ros.process.pooled_executor import PooledExecutor
from modal_spring_ros.ros.process.stop_signals import (end_ros, spin_until_stopped, STOP_SIGNALS,
                                                       StopSignals)
import pytest
import rclpy
from rclpy.context import Context
from rclpy.exceptions import InvalidHandle
from ros_harness import DOMAIN_ID, wait_for

#: the threads a streaming node runs beside its executor
NODE_THREADS = ('modal_spring_sim', 'modal_spring_inputs', 'modal_spring_tf', 'parameter_changes')


@pytest.fixture
def own_signals():
    """Give the test SIGINT and SIGTERM, and give them back to pytest after."""
    before = {number: signal.getsignal(number) for number in STOP_SIGNALS}
    yield
    for number, handler in before.items():
        signal.signal(number, handler)


def test_a_first_signal_interrupts_only_while_starting_and_a_second_always(own_signals):
    stop = StopSignals().install()
    with pytest.raises(KeyboardInterrupt):              # starting: a long computation ends
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(0.01)                                # the handler runs here
    assert stop.requested.is_set()

    stop = StopSignals().install()
    stop.interrupting = False                           # streaming
    os.kill(os.getpid(), signal.SIGINT)
    time.sleep(0.01)
    assert stop.requested.is_set()                      # asked, nothing raised
    with pytest.raises(KeyboardInterrupt):              # a second signal forces it
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.01)


@pytest.mark.ros
@pytest.mark.parametrize('number', STOP_SIGNALS, ids=lambda n: signal.Signals(n).name)
def test_a_signal_while_streaming_ends_the_spin_and_leaves_ros_up_until_the_node_stopped(
        own_signals, number):
    context = Context()
    rclpy.init(context=context, domain_id=DOMAIN_ID)
    stop = StopSignals().install()
    node = ModalSpringNode(stop=stop, context=context, namespace='stop_signals')
    try:
        executor = PooledExecutor(2, context=context)
        executor.add_node(node)
        stop.interrupting = False
        spinning = threading.Thread(target=spin_until_stopped, args=(executor, stop),
                                    daemon=True)
        spinning.start()
        assert wait_for(lambda: node.sim.steps > 0, 60), 'the node never stepped'
        os.kill(os.getpid(), number)
        time.sleep(0.01)
        spinning.join(10.0)
        assert not spinning.is_alive(), 'the spin loop did not end on the signal'
        # ROS is up while the node's own threads are stopped and joined ...
        assert context.ok()
        assert any(t.name in NODE_THREADS for t in threading.enumerate())
        node.stop()
        assert context.ok()
        assert [t.name for t in threading.enumerate() if t.name in NODE_THREADS] == []
    finally:
        node.stop()
        node.destroy_node()
        end_ros(context)


def test_ending_ros_shuts_the_context_down_and_destroys_it_the_default_one_made_anew():
    """
    A process's participant goes at ``end_ros``, not among what the interpreter's exit collects.

    The context is shut down and destroyed (the middleware's participant with it); the default
    context is replaced, so ``rclpy.init`` works again in the process.
    """
    for default in (True, False):
        context = rclpy.get_default_context() if default else Context()
        rclpy.init(context=context, domain_id=DOMAIN_ID)
        node = rclpy.create_node('end_ros', context=context)
        assert context.ok() and node.count_publishers('/rosout') >= 0
        node.destroy_node()
        end_ros(None if default else context)
        with pytest.raises(InvalidHandle):      # destroyed: not even asked whether it is up
            context.ok()
        assert rclpy.get_default_context() is not context and not rclpy.ok()

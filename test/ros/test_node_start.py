"""
A node whose start is cut short (Ctrl-C, a failure) stops what it started before it raises.

``modal_spring_node`` has no node to stop when its constructor raises; a simulation thread left
publishing into the interpreter's exit could crash the process after Ctrl-C.
"""
from __future__ import annotations

import threading

from modal_spring_ros.ros import node as node_module
from modal_spring_ros.ros.inputs.input_node import InputNode
from modal_spring_ros.ros.node import ModalSpringNode
import pytest
import rclpy
from rclpy.context import Context
from rclpy.exceptions import InvalidHandle
from ros_harness import DOMAIN_ID

pytestmark = pytest.mark.ros

#: the threads a node starts (simulation, inputs, parameter changes)
NODE_THREADS = ('modal_spring_sim', 'modal_spring_inputs', 'modal_spring_tf', 'parameter_changes')


def node_threads() -> list[str]:
    return [t.name for t in threading.enumerate() if t.name in NODE_THREADS and t.is_alive()]


@pytest.mark.parametrize('stage', ['services_made', 'threads_started'])
def test_a_start_interrupted_leaves_no_thread_and_no_node(stage, monkeypatch):
    assert node_threads() == []
    started, nodes = [], []
    real_init, real_start = InputNode.__init__, InputNode.start

    def recorded(self, node, *args, **kwargs):
        real_init(self, node, *args, **kwargs)
        nodes.extend([node, self.node])
    monkeypatch.setattr(InputNode, '__init__', recorded)
    if stage == 'services_made':
        def interrupted(*args, **kwargs):
            raise KeyboardInterrupt
        monkeypatch.setattr(node_module, 'RunServices', interrupted)   # making the services
    else:
        def interrupted(self):
            real_start(self)
            if self.node.get_name().endswith('_tf'):     # the last thread the node starts
                started.extend(node_threads())
                raise KeyboardInterrupt
        monkeypatch.setattr(InputNode, 'start', interrupted)
    context = Context()
    rclpy.init(context=context, domain_id=DOMAIN_ID)
    try:
        with pytest.raises(KeyboardInterrupt):
            ModalSpringNode(context=context, namespace=f'cut_{stage}')
        assert node_threads() == []
        assert len({id(node) for node in nodes}) == 3
        for node in nodes:     # the node and its input and TF companions were destroyed
            with pytest.raises(InvalidHandle):
                with node.handle:
                    pass
    finally:
        rclpy.try_shutdown(context=context)
    if stage == 'threads_started':
        assert sorted(started) == sorted(NODE_THREADS)

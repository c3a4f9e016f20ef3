"""
The recorder's snapshot of a node's parameters, asked over real DDS.

``snapshot_parameters`` asks ``list_parameters`` then ``get_parameters``; a query unanswered
for ``ASK_AGAIN_S`` is asked again (a new client's first answer can be lost on a busy machine),
and a node that never answers gives None by the timeout.
"""
from __future__ import annotations

import contextlib
import time

from modal_spring_ros.ros.tools import recorder
from modal_spring_ros.ros.tools.recorder import snapshot_parameters
import pytest
from rcl_interfaces.msg import ParameterType, ParameterValue
from rcl_interfaces.srv import GetParameters, ListParameters
import rclpy
from rclpy.signals import SignalHandlerOptions
from ros_harness import Client, DOMAIN_ID

pytestmark = pytest.mark.ros


class SlowParameters:
    """A node's two parameter queries; the first ``late`` list requests answered too late."""

    def __init__(self, client: Client, name: str, late: int, delay_s: float):
        self.listed = 0
        self.late, self.delay_s = late, delay_s
        client.node.create_service(ListParameters, f'/{name}/list_parameters', self._list)
        client.node.create_service(GetParameters, f'/{name}/get_parameters', self._get)

    def _list(self, request, response):
        self.listed += 1
        if self.listed <= self.late:
            time.sleep(self.delay_s)
        response.result.names = ['scene', 'publish_rate_hz']
        return response

    def _get(self, request, response):
        values = {'scene': ParameterValue(type=ParameterType.PARAMETER_STRING,
                                          string_value='sheet_10x10'),
                  'publish_rate_hz': ParameterValue(type=ParameterType.PARAMETER_DOUBLE,
                                                    double_value=30.0)}
        response.values = [values[n] for n in request.names]
        return response


@contextlib.contextmanager
def asked(name: str, late: int, delay_s: float):
    """
    Yield a node's slow parameter services and a node to ask them from, then end both.

    The asker is in the default context, as ``modal_spring_record`` makes its node.
    """
    server = Client(f'{name}_server')
    slow = SlowParameters(server, name, late=late, delay_s=delay_s)
    # rclpy's own Ctrl-C handling is the suite's to keep: with it, Ctrl-C would shut the
    # default context down instead of interrupting pytest
    rclpy.init(domain_id=DOMAIN_ID, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(f'{name}_asker')
    try:
        yield slow, node
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
        server.close()


def test_a_query_answered_too_late_is_asked_again(monkeypatch):
    monkeypatch.setattr(recorder, 'ASK_AGAIN_S', 1.0)
    with asked('slow_node', late=1, delay_s=2.0) as (slow, node):
        assert snapshot_parameters(node, '/slow_node', timeout=20.0) == {
            'scene': 'sheet_10x10', 'publish_rate_hz': 30.0}
        assert slow.listed >= 2                     # asked again (the server answers in turn)


def test_a_node_that_never_answers_gives_none_by_the_timeout(monkeypatch):
    monkeypatch.setattr(recorder, 'ASK_AGAIN_S', 0.5)
    with asked('mute_node', late=100, delay_s=3.0) as (slow, node):
        start = time.monotonic()
        assert snapshot_parameters(node, '/mute_node', timeout=2.0) is None
        assert time.monotonic() - start >= 1.9 and slow.listed >= 1   # waited out its timeout

"""
The node's on-set callback only validates; what a change does happens after the set.

The node runs in this process, so the test sees the order in which a parameter is set and its
change reaches the simulation thread (rclcpp's rule for on-set callbacks: no side effect).
"""
from __future__ import annotations

from modal_spring_ros.ros.changes.requests import ChangeBand
import pytest
from rcl_interfaces.msg import SetParametersResult
from rclpy.parameter import Parameter
from ros_harness import node_in_process, wait_for

pytestmark = pytest.mark.ros


@pytest.fixture
def node():
    low = [Parameter('filter.type', value='lowpass'), Parameter('filter.high_hz', value=20.0)]
    with node_in_process('sets', low) as running:
        yield running


def test_a_band_reaches_the_run_only_after_its_parameter_is_set(node):
    seen = []          # (request type, filter.high_hz as set when it was handed over)
    submit = node._thread.submit

    def watch(request):
        seen.append((type(request), node.get_parameter('filter.high_hz').value))
        submit(request)
    node._thread.submit = watch
    (result,) = node.set_parameters([Parameter('filter.high_hz', value=9.0)])
    assert result.successful, result.reason
    assert wait_for(lambda: (ChangeBand, 9.0) in seen, 10.0), seen
    assert (ChangeBand, 20.0) not in seen and all(v == 9.0 for _, v in seen), seen
    assert wait_for(lambda: node.sim.describe_band().endswith('9 Hz'), 10.0), \
        node.sim.describe_band()


def test_a_request_refused_after_the_node_validated_it_changes_nothing(node):
    """Another on-set callback refuses what the node accepted: no band change, no value."""
    band = node.sim.describe_band()
    seen = []
    submit = node._thread.submit
    node._thread.submit = lambda request: (seen.append(request), submit(request))

    def veto(params):
        return SetParametersResult(successful=False, reason='vetoed')
    node.add_on_set_parameters_callback(veto)
    try:
        # rclpy calls the callback added last first: put the node's own in front of the veto
        node._on_set_parameters_callbacks.reverse()
        (result,) = node.set_parameters([Parameter('filter.high_hz', value=7.0)])
        assert not result.successful and result.reason == 'vetoed'
    finally:
        node.remove_on_set_parameters_callback(veto)
    assert node.get_parameter('filter.high_hz').value == 20.0
    (result,) = node.set_parameters([Parameter('filter.high_hz', value=8.0)])   # goes on
    assert result.successful
    assert wait_for(lambda: node.sim.describe_band().endswith('8 Hz'), 10.0)
    assert node._preparer.wait_idle(10.0)
    assert [r.band.high for r in seen if isinstance(r, ChangeBand)] == [8.0]   # never 7 Hz
    assert 'filter.high_hz=7.0 dropped: refused after' in node._preparer.state().reverted
    assert band != node.sim.describe_band()


def test_gains_set_while_running_reach_the_run_and_an_impossible_one_changes_nothing(node):
    (result,) = node.set_parameters([Parameter('filter.gains', value='0:5:6')])
    assert result.successful, result.reason
    assert wait_for(lambda: node.sim.band.gains == ('0:5:6',), 10.0), node.sim.describe_band()
    (result,) = node.set_parameters([Parameter('filter.gains', value='0:5:600')])
    assert not result.successful
    assert result.reason == "filter.gains: '0:5:600': 600 dB is beyond +-60 dB"
    assert node.get_parameter('filter.gains').value == '0:5:6'
    assert node.sim.band.gains == ('0:5:6',)

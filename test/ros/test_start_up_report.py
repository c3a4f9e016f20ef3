"""A node's progress on /diagnostics while it prepares its first frame, over real DDS."""
from __future__ import annotations

import time

from diagnostic_msgs.msg import DiagnosticArray
from modal_spring_ros.ros.start.start_up_report import PERIOD_S, StartUpReport
import pytest
from rcl_interfaces.msg import Log
import rclpy
from ros_harness import Client, wait_for

pytestmark = pytest.mark.ros


def messages(received: list, node: str) -> list[str]:
    return [status.message for _, msg in list(received) for status in msg.status
            if any(kv.key == 'node' and kv.value == node for kv in status.values)]


def test_a_starting_node_publishes_its_last_progress_line_until_it_streams():
    client = Client('start_up_report_client')
    node = rclpy.create_node('starting', namespace='report', context=client.context)
    try:
        received = client.collect(DiagnosticArray, '/diagnostics')
        report = StartUpReport(node, 'sheet_316x316')
        with report:
            report.progress('factorising the 199080-DOF stiffness')
            assert wait_for(lambda: 'starting: factorising the 199080-DOF stiffness'
                            in messages(received, '/report/starting'), 10)
            report.progress('computing the 8 lowest modes')
            assert wait_for(lambda: 'starting: computing the 8 lowest modes'
                            in messages(received, '/report/starting'), 10)
        # its publisher is gone with the block: the running node's own reports take over
        publishing = node.get_publisher_names_and_types_by_node('starting', '/report')
        assert '/rosout' in dict(publishing) and '/diagnostics' not in dict(publishing)
        published = len(messages(received, '/report/starting'))
        time.sleep(3 * PERIOD_S)
        assert len(messages(received, '/report/starting')) == published
        # the last line is kept for a change that began before it, not for a later one
        assert report.latest() == 'computing the 8 lowest modes'
        assert report.latest(since=time.monotonic()) == ''
    finally:
        node.destroy_node()
        client.close()


def test_a_stage_that_lasts_is_logged_again_with_its_time():
    """A console following the log sees the node at work (every 5 s by default; 1.5 s here)."""
    client = Client('start_up_log_client')
    node = rclpy.create_node('lasting', namespace='report', context=client.context)
    try:
        logged = client.collect(Log, '/rosout', qos=100)

        def lines():
            return [m.msg for _, m in list(logged) if m.name == 'report.lasting']
        with StartUpReport(node, 'sheet_316x316', line_period_s=1.5) as report:
            report.progress('computing the 32 lowest modes')
            lasting = 'computing the 32 lowest modes (still at it: '
            assert wait_for(lambda: any(line.startswith(lasting) for line in lines()), 10)
            again = [line for line in lines() if 'still at it' in line]
            seconds = int(again[0].split('still at it: ')[1].split(' s')[0])
            assert 1 <= seconds <= 4
    finally:
        node.destroy_node()
        client.close()

"""
The node watches its automatic plan while it streams, and falls back beyond its tolerance.

Over real DDS, the node in its own process.

The plan (``sheet_10x10`` at 1 %: rest modes, refreshed forces) is measured again from the run's
state every two simulated seconds. A click pulls the sheet's corner with 5 N, far from anything
the pilot measured: the next window is beyond the tolerance, ``/diagnostics`` says so, and the
node sets its own parameters to the full run the pilot measured (``modal.auto`` off, ``method``
full, its step), so the parameters, ``/parameter_events`` and the capture say what runs. The
capture re-simulates frame for frame through the fallback.
"""
from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PointStamped
from modal_spring_ros.bags.messages.pointcloud import xyz
import numpy as np
import pytest
from ros_harness import (assert_resimulates_exactly, frames_since, node_of, node_with_client,
                         wait_for)
from sensor_msgs.msg import PointCloud2

pytestmark = pytest.mark.ros

NODE = '/watch/modal_spring'


def latest_status(diags: list) -> tuple[DiagnosticStatus | None, dict]:
    for _, d in reversed(list(diags)):
        s = d.status[0]
        if node_of(s) == NODE:
            return s, {kv.key: kv.value for kv in s.values}
    return None, {}


def test_a_pull_beyond_the_automatic_plan_is_caught_and_the_node_falls_back(tmp_path):
    bag = tmp_path / 'watched'
    with node_with_client('modal.auto:=true', 'modal.watch:=2.0', 'interaction.max_force_n:=5.0',
                          'interaction.hold_s:=60.0', f'record.bag:={bag}',
                          namespace='watch') as (node, client):
        points = client.collect(PointCloud2, '/watch/points', qos=500)
        diags = client.collect(DiagnosticArray, '/diagnostics')
        pub = client.node.create_publisher(PointStamped, '/clicked_point', 10)
        assert wait_for(lambda: len(points) > 5 and pub.get_subscription_count() > 0, 60)
        # a first window from the run's own state, within the tolerance
        assert wait_for(lambda: latest_status(diags)[1].get(
            'automatic choice watched', '').startswith('1 window: last '), 60)
        status, values = latest_status(diags)
        watched = values['automatic choice watched']
        # within the tolerance: no watch warning (a busy host may warn of its real-time factor)
        assert 'against the full run' in watched and status.level != DiagnosticStatus.ERROR
        assert 'beyond its tolerance' not in status.message, status.message
        error = float(watched.split('last ')[1].split('%')[0]) / 100
        assert 0.0 < error <= 0.01
        # a pull far beyond anything the pilot measured
        before = xyz(points[-1][1])
        corner = int(np.argmax(before[:, 0] - before[:, 2]))
        click = PointStamped()
        click.header.frame_id = 'world'
        click.point.x, click.point.y, click.point.z = (float(before[corner, 0] + 0.5),
                                                       float(before[corner, 1]),
                                                       float(before[corner, 2]))
        pub.publish(click)
        assert wait_for(lambda: client.get_parameters(NODE[1:], 'method')[0] == 'full', 60)
        method, auto, dt, integrator = client.get_parameters(
            NODE[1:], 'method', 'modal.auto', 'sim.dt', 'integrator')
        assert (method, auto, integrator) == ('full', False, 'explicit') and dt > 0.0
        # /diagnostics says why, with the window's error beyond the tolerance, as a WARN
        assert wait_for(lambda: latest_status(diags)[1].get('method') == 'full', 30)
        status, values = latest_status(diags)
        assert status.level == DiagnosticStatus.WARN
        assert 'automatic plan beyond its tolerance 1.00%' in status.message
        assert 'falling back to the full run' in status.message
        beyond = float(status.message.split('%: ')[1].split('%')[0]) / 100
        assert beyond > 0.01
        # the stream goes on, finite, pulled by the full run
        for m in frames_since(points, points[-1][0], 20):
            assert np.isfinite(xyz(m)).all()
    # the capture holds the plan taken over from the full run the node streamed first, and the
    # fallback, as the parameter changes they were: re-simulated frame for frame through both
    # (the plan's pilot, the click, the fallback's rebuild at its step)
    assert assert_resimulates_exactly(bag, tmp_path / 'again', changes=2) > 100

"""
``modal_spring_view``: the stream in Foxglove, checked with a WebSocket client as Foxglove is.

The view and the node it starts run as a user runs them (one command, ``--start-node``); the
client speaks the Foxglove WebSocket protocol (subprotocol ``foxglove.sdk.v1``): it reads the
advertised channels, subscribes to the points and decodes a cloud from the bytes it gets.
"""
from __future__ import annotations

import json
import socket
import struct
import time

from modal_spring_ros.cli.launcher import EXIT_INTERRUPTED
from modal_spring_ros.cli.modal_spring_view import main
import numpy as np
import pytest
from rclpy.serialization import deserialize_message
from ros_harness import console_script, interrupted_inside, NodeProcess, stderr_excerpt
from sensor_msgs.msg import PointCloud2

pytestmark = pytest.mark.ros
websockets_client = pytest.importorskip('websockets.sync.client')
websockets_exceptions = pytest.importorskip('websockets.exceptions')

#: Foxglove's WebSocket protocol: the subprotocol, and the opcode of a message's data
SUBPROTOCOL, MESSAGE_DATA = 'foxglove.sdk.v1', 1


def free_port() -> int:
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


def connect(port: int, timeout: float = 60.0):
    """Return a client connected to the view on ``port``, once it listens (after ROS starts)."""
    end = time.monotonic() + timeout
    while True:
        try:
            return websockets_client.connect(f'ws://127.0.0.1:{port}', subprotocols=[SUBPROTOCOL],
                                             max_size=None, open_timeout=10)
        except OSError:
            if time.monotonic() > end:
                raise
            time.sleep(0.2)


def advertised(ws, wanted: set[str], timeout: float = 30.0) -> dict:
    """Return the channels the server advertised by topic, once every wanted one is."""
    channels: dict = {}
    end = time.monotonic() + timeout
    while not wanted <= set(channels):
        message = ws.recv(timeout=max(0.1, end - time.monotonic()))
        if isinstance(message, str):
            op = json.loads(message)
            if op['op'] == 'advertise':
                channels.update({c['topic']: c for c in op['channels']})
    return channels


def test_the_view_serves_the_stream_to_a_foxglove_client():
    port = free_port()
    view = NodeProcess(argv=[console_script('modal_spring_view'), '--start-node', '--port',
                             str(port), '--ros-args', '-r', '__ns:=/view'])
    try:
        with connect(port) as ws:
            channels = advertised(ws, {'/view/points', '/view/mesh', '/diagnostics', '/tf',
                                       '/tf_static'})
            points = channels['/view/points']
            assert (points['encoding'], points['schemaName'], points['schemaEncoding']) == (
                'cdr', 'sensor_msgs/msg/PointCloud2', 'ros2msg')
            assert 'MSG: sensor_msgs/PointField' in points['schema']
            assert channels['/view/mesh']['schemaName'] == 'visualization_msgs/msg/Marker'
            ws.send(json.dumps({'op': 'subscribe',
                                'subscriptions': [{'id': 7, 'channelId': points['id']}]}))
            clouds = []
            end = time.monotonic() + 60.0
            while len(clouds) < 3 and time.monotonic() < end:
                message = ws.recv(timeout=max(0.1, end - time.monotonic()))
                if isinstance(message, bytes) and message[0] == MESSAGE_DATA:
                    subscription, _ = struct.unpack_from('<IQ', message, 1)
                    assert subscription == 7
                    clouds.append(deserialize_message(message[13:], PointCloud2))
    except BaseException:
        view.kill()
        raise
    code, _, err = view.interrupt(timeout=30.0)
    assert code == 0 and 'Traceback' not in err, stderr_excerpt(err)
    assert len(clouds) == 3
    cloud = clouds[-1]
    assert (cloud.width, cloud.header.frame_id) == (100, 'world')      # sheet_10x10
    xyz = np.frombuffer(bytes(cloud.data), dtype='<f4').reshape(100, -1)[:, :3]
    assert np.isfinite(xyz).all() and np.ptp(xyz[:, 0]) > 0.5           # the sheet, 0.9 m wide
    assert 'streaming sheet_10x10' in err                                # the node it started


@pytest.mark.parametrize('argv, message', [
    (['--port', '70000'], '--port (70000) must be from 0 to 65535'),
    (['--max-rate-hz', '0'], '--max-rate-hz (0.0) must be above 0'),
])
def test_bad_view_options_are_refused_by_name(argv, message, capsys):
    assert main(argv) == 2
    assert message in capsys.readouterr().err


def test_a_client_flooding_the_view_with_unknown_channels_costs_a_few_log_lines():
    port = free_port()
    view = NodeProcess(argv=[console_script('modal_spring_view'), '--start-node', '--port',
                             str(port)])
    try:
        ws = connect(port)
        advertised(ws, {'/points'})
        try:
            for k in range(3000):
                ws.send(json.dumps({'op': 'subscribe', 'subscriptions': [
                    {'id': 5000 + k, 'channelId': 900000 + k}]}))
        except websockets_exceptions.ConnectionClosed:
            # the server answers each with a status this client never reads; where its queue
            # of answers fills (a busy machine), it drops the client, as the SDK documents
            pass
        time.sleep(2.0)
        ws.close()
    finally:
        code, _, err = view.interrupt(timeout=30.0)
    assert code == 0, stderr_excerpt(err)
    refused = [line for line in err.splitlines() if 'unknown channel' in line]
    assert len(refused) == 5 and 'counted, not shown' in refused[-1], refused


def test_ctrl_c_as_the_view_subscribes_ends_it_quietly():
    """
    Ctrl-C between the server's start and the subscriptions' end: no error, no traceback.

    rclpy's own handler shut ROS down there, and the subscription that then failed was
    reported as the port refused (exit 2). Now a signal only asks the view to stop: it
    subscribes, serves and stops at once.
    """
    done = interrupted_inside('modal_spring_ros.ros.tools.live_view', 'Forwarded',
                              'modal_spring_ros.cli.modal_spring_view', '--port',
                              str(free_port()))
    assert done.returncode in (0, EXIT_INTERRUPTED), stderr_excerpt(done.stderr)
    assert 'Traceback' not in done.stderr and 'error:' not in done.stderr, \
        stderr_excerpt(done.stderr)


@pytest.mark.parametrize('moment', ['rclpy', 'serving'])
def test_ctrl_c_while_the_view_starts_or_serves_ends_it_quietly(moment):
    """An interrupt while rclpy loads, or once the view serves: no error, no traceback."""
    view = NodeProcess(argv=[console_script('modal_spring_view'), '--port', str(free_port())])
    end = time.monotonic() + 60.0
    reached = {'rclpy': lambda: '_rclpy_pybind11' in _maps(view.proc.pid),
               'serving': lambda: 'serving' in view.stderr()}[moment]
    while not reached():
        assert time.monotonic() < end and view.proc.poll() is None, stderr_excerpt(view.stderr())
        time.sleep(0.001)
    code, _, err = view.interrupt(timeout=30.0)
    assert code in (0, EXIT_INTERRUPTED), stderr_excerpt(err)
    assert 'Traceback' not in err and 'error:' not in err, stderr_excerpt(err)


def _maps(pid: int) -> str:
    try:
        with open(f'/proc/{pid}/maps') as maps:
            return maps.read()
    except OSError:
        return ''

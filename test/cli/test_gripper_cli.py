"""modal_spring_gripper: one command starts a node and carries its clamp around (over DDS)."""
from __future__ import annotations

import os
import signal
import subprocess

from modal_spring_ros.bags.messages.pointcloud import xyz
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest
from ros_harness import Client, console_script, interrupted_inside, wait_for
from sensor_msgs.msg import PointCloud2


@pytest.mark.ros
def test_the_gripper_starts_a_node_that_follows_it():
    fixed = np.flatnonzero(load_scene('sheet_10x10').fixed)
    proc = subprocess.Popen([console_script('modal_spring_gripper'), '--start-node',
                             '--duration', '10', '--ramp-s', '0.5', '--ros-args', '-r',
                             '__ns:=/grip'], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)   # its node in its group
    client = Client('gripper_client')        # after the processes, as the node tests do
    points = client.collect(PointCloud2, '/grip/points', qos=500)
    try:
        if not wait_for(lambda: len(points) > 10, 60):
            os.killpg(proc.pid, signal.SIGKILL)
            raise AssertionError(f'no stream from the node: {proc.communicate()[1][-3000:]}')
        rest = load_scene('sheet_10x10').rest_positions[fixed]
        # the clamp circles 0.1 m and turns +-30 degrees: its row leaves its rest place
        assert wait_for(lambda: np.abs(xyz(points[-1][1])[fixed] - rest).max() > 0.02, 15)
        out, err = proc.communicate(timeout=40)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)             # the gripper and its node
        client.close()
    assert proc.returncode == 0, err[-2000:]
    assert 'Traceback' not in err
    for _, m in points:
        assert np.isfinite(xyz(m)).all()


def test_bad_options_are_refused_with_one_line():
    proc = subprocess.run([console_script('modal_spring_gripper'), '--rate-hz', '0'],
                          capture_output=True, text=True, timeout=30)
    assert proc.returncode == 2
    assert proc.stderr.strip() == ('modal_spring_gripper: error: --rate-hz (0.0) must be '
                                   'above 0 and at most 1000')


@pytest.mark.ros
def test_ctrl_c_as_the_gripper_publishes_ends_it_cleanly():
    """
    A signal asks the gripper to stop: it stops at once, no traceback.

    rclpy's own handler shut ROS down under the pose being published (a traceback).
    """
    done = interrupted_inside('modal_spring_ros.cli.modal_spring_gripper', 'gripper_pose',
                              'modal_spring_ros.cli.modal_spring_gripper', '--duration', '30',
                              '--ros-args', '-r', '__ns:=/stopped_gripper')
    assert done.returncode == 0 and 'Traceback' not in done.stderr, done.stderr[-3000:]

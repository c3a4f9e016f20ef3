"""The node lets a waiting thread run within half a millisecond, not Python's five."""
from __future__ import annotations

import subprocess
import sys

from modal_spring_ros.ros.process.interpreter_switching import SWITCH_INTERVAL_S

# Stops the node at rclpy.init, printing the interval its interpreter switches threads at.
AT_INIT = """
import sys, rclpy
def init(*args, **kwargs):
    print('switch interval at init:', sys.getswitchinterval())
    sys.exit(0)
rclpy.init = init
from modal_spring_ros.cli.modal_spring_node import main
main([])
"""


def test_the_node_switches_threads_ten_times_as_often_as_python_does():
    done = subprocess.run([sys.executable, '-c', AT_INIT], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 0, done.stderr[-2000:]
    said = done.stdout.strip().splitlines()[-1]
    assert said == f'switch interval at init: {SWITCH_INTERVAL_S}', done.stdout

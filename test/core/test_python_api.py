"""The Python API page's example runs as written, with every ROS package hidden."""
from __future__ import annotations

import re
import subprocess
import sys

from helpers import HIDE_ROS, REPO


def test_the_documented_example_runs_without_ros():
    page = (REPO / 'docs' / 'python_api.md').read_text()
    (example,) = re.findall(r'```python\n(.*?)```', page, flags=re.S)
    done = subprocess.run([sys.executable, '-c', HIDE_ROS + example], capture_output=True,
                          text=True, timeout=300, cwd=REPO)
    assert done.returncode == 0, done.stderr[-2000:]
    lines = done.stdout.splitlines()
    assert "'sheet_10x10'" in lines[0]
    assert re.fullmatch(r'modal \d+ coordinates, dt [0-9.e-]+ s', lines[1])
    moved = float(re.search(r'largest move ([0-9.]+) m', lines[2]).group(1))
    assert re.search(r't = 1\.00 s', lines[2]) and moved > 0.0
    assert lines[3] == 'bandpass 1..8 Hz'


def test_hiding_ros_really_hides_it():
    done = subprocess.run([sys.executable, '-c', HIDE_ROS + 'import rclpy'], capture_output=True,
                          text=True, timeout=60)
    assert done.returncode != 0 and 'hidden' in done.stderr

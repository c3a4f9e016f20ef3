"""
Python without ROS: the Python API page's example, the simulator and the scripts that need ROS.

Twice: in this interpreter with every ROS package hidden, and in ``.venv-noros``, the venv
``.ci/bootstrap test`` makes with ``pip install -e .`` alone (no ROS wheels), as a user without ROS
has it (``MODAL_SPRING_NOROS_PYTHON`` names another; skipped where there is none).
"""
from __future__ import annotations

import json
import os
from pathlib import Path
import re
import subprocess
import sys

from helpers import BAGS, HIDE_ROS, REPO
import numpy as np
import pytest

#: The interpreter of a venv without the ROS wheels.
NOROS_PYTHON = Path(os.environ.get('MODAL_SPRING_NOROS_PYTHON',
                                   REPO / '.venv-noros' / 'bin' / 'python'))
needs_noros = pytest.mark.skipif(not NOROS_PYTHON.exists(),
                                 reason=f'no venv without ROS at {NOROS_PYTHON}: run '
                                        '.ci/bootstrap test')
WAYS = [pytest.param((sys.executable, HIDE_ROS), id='ros-hidden'),
        pytest.param((str(NOROS_PYTHON), ''), id='venv-without-ros', marks=needs_noros)]


@pytest.mark.parametrize('way', WAYS)
def test_the_documented_example_runs_without_ros(way):
    python, prelude = way
    page = (REPO / 'docs' / 'python_api.md').read_text()
    # the page's examples, run in turn (the later ones go on with the first one's run)
    example = '\n'.join(re.findall(r'```python\n(.*?)```', page, flags=re.S))
    done = subprocess.run([python, '-c', prelude + example], capture_output=True,
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


@pytest.mark.slow
@needs_noros
def test_the_venv_without_ros_has_none_and_its_simulator_runs_a_mesh_scene(tmp_path):
    for module in ('rclpy', 'sensor_msgs', 'ament_index_python'):
        done = subprocess.run([str(NOROS_PYTHON), '-c', f'import {module}'],
                              capture_output=True, text=True, timeout=60)
        assert 'ModuleNotFoundError' in done.stderr, module
    bin_dir = NOROS_PYTHON.parent
    out = tmp_path / 'cloth.npz'
    done = subprocess.run([str(bin_dir / 'modal_spring_sim'), '--scene', 'cloth_3d',
                           '--duration', '0.02', '--quiet', '--output', str(out)],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    positions = np.load(out)['positions']
    assert positions.shape[1:] == (400, 3) and np.isfinite(positions).all()
    # a script that needs ROS says so in one line, and how to get it
    done = subprocess.run([str(bin_dir / 'modal_spring_node')], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 2
    assert re.fullmatch(r'modal_spring_node: needs \S+, which is not installed: pip install '
                        r"'\.\[ros\]' \(ROS 2 Jazzy from PyPI wheels\), or source a ROS 2 "
                        r'install', done.stderr.strip()), done.stderr


@pytest.mark.slow
@needs_noros
def test_without_ros_a_bag_is_read_compared_and_drawn_from_its_own_schemas(tmp_path):
    """The bags carry their message definitions: looking at a run needs no ROS install."""
    bin_dir = NOROS_PYTHON.parent
    full, lowpass = BAGS / 'sheet_10x10_full', BAGS / 'sheet_10x10_lowpass_0_14'
    report = tmp_path / 'compare.json'
    done = subprocess.run([str(bin_dir / 'modal_spring_compare'), str(full), str(lowpass),
                           '--json', str(report), '--plot', str(tmp_path / 'compare.png')],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    # the same figures as the ROS venv reads from the same bags
    compare = Path(sys.executable).parent / 'modal_spring_compare'
    with_ros = subprocess.run([str(compare), str(full), str(lowpass),
                               '--json', str(tmp_path / 'ros.json')],
                              capture_output=True, text=True, timeout=300)
    assert with_ros.returncode == 0, with_ros.stderr[-2000:]
    assert json.loads(report.read_text()) == json.loads((tmp_path / 'ros.json').read_text())
    assert (tmp_path / 'compare.png').stat().st_size > 10_000
    done = subprocess.run([str(bin_dir / 'modal_spring_render'), str(full), '--output',
                           str(tmp_path / 'sheet.png'), '--snapshots', '3'],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert (tmp_path / 'sheet.png').stat().st_size > 10_000


def test_the_package_is_the_python_apis_facade_and_loads_nothing_until_used():
    """Each name is its module's own object; ``import modal_spring_ros`` loads no numpy."""
    import importlib
    import modal_spring_ros
    for name, module in modal_spring_ros.API.items():
        assert getattr(modal_spring_ros, name) is getattr(importlib.import_module(module), name)
    assert set(modal_spring_ros.API) <= set(dir(modal_spring_ros))
    with pytest.raises(AttributeError, match='no attribute'):
        modal_spring_ros.not_a_name  # noqa: B018
    code = ('import sys, modal_spring_ros\n'
            "print(sorted(m for m in ('numpy', 'scipy', 'rclpy') if m in sys.modules))")
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         timeout=60, check=True).stdout
    assert out.strip() == '[]'

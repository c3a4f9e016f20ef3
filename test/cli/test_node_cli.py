"""modal_spring_node's own command line: --help prints the parameters and exits."""
from __future__ import annotations

import subprocess

from modal_spring_ros.ros.parameters import PARAMETERS
from ros_harness import console_script


def test_help_prints_every_parameter_and_exits_without_starting():
    proc = subprocess.run([console_script('modal_spring_node'), '--help'], capture_output=True,
                          text=True, timeout=30)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith('usage: modal_spring_node [-h] [--ros-args')
    for name, (default, descriptor) in PARAMETERS.items():
        flag = ', read-only' if descriptor.read_only else ''
        assert f'\n  {name} (default {default!r}{flag})\n' in proc.stdout
        assert descriptor.description.split()[0] in proc.stdout
    assert "  scene (default 'sheet_10x10', read-only)" in proc.stdout
    assert proc.stderr == ''  # nothing started: no log line

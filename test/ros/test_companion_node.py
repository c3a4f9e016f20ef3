"""A node a tool starts (``--start-node``) ends with the tool, however the tool ends."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

from helpers import stat_fields
from modal_spring_ros.ros.process.companion_node import start_companion, stop_companion
import pytest

linux_only = pytest.mark.skipif(not sys.platform.startswith('linux'),
                                reason='a companion outlives a killed tool where no '
                                       'PR_SET_PDEATHSIG exists')


def running(pid: int) -> bool:
    """Return whether ``pid`` runs (a zombie waiting for its reaper does not)."""
    try:
        return stat_fields(pid)[0] not in ('Z', 'X')
    except (FileNotFoundError, ProcessLookupError):
        return False


def test_a_companion_gets_its_arguments_and_gives_its_exit_status():
    child = start_companion([sys.executable, '-c', 'import sys; sys.exit(7 * (sys.argv[1:] == '
                             '["a b", "--ros-args"]))', 'a b', '--ros-args'])
    assert child.wait(30.0) == 7


def test_a_companion_is_stopped_as_ctrl_c_would():
    child = start_companion([sys.executable, '-c', textwrap.dedent("""
        import time
        try:
            time.sleep(60)
        except KeyboardInterrupt:
            raise SystemExit(3)""")])
    time.sleep(1.0)     # past the interpreter's start, into the sleep
    stop_companion(child, timeout=30.0)
    assert child.returncode == 3


@linux_only
@pytest.mark.parametrize('end', [signal.SIGKILL, signal.SIGSEGV])
def test_a_companion_ends_with_a_tool_that_is_killed_or_crashes(end):
    tool = subprocess.Popen([sys.executable, '-c', textwrap.dedent("""
        import sys, time
        from modal_spring_ros.ros.process.companion_node import start_companion
        child = start_companion([sys.executable, '-c', 'import time; time.sleep(120)'])
        print(child.pid, flush=True)
        time.sleep(120)""")], stdout=subprocess.PIPE, text=True, start_new_session=True)
    try:
        pid = int(tool.stdout.readline())
        assert running(pid)
        os.kill(tool.pid, end)
        assert tool.wait(30.0) == -end
        deadline = time.monotonic() + 30.0
        while running(pid) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not running(pid)
    finally:
        os.killpg(tool.pid, signal.SIGKILL)
        tool.stdout.close()

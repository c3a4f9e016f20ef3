"""modal_spring_node's own command line: --help, the spin loop, Ctrl-C while starting."""
from __future__ import annotations

from pathlib import Path
import signal
import subprocess
import threading
import time

from modal_spring_ros.cli.launcher import EXIT_INTERRUPTED
from modal_spring_ros.ros.parameters import PARAMETERS
from modal_spring_ros.ros.process.pooled_executor import PooledExecutor
from modal_spring_ros.ros.process.stop_signals import spin_until_stopped
import pytest
import rclpy
from rclpy.context import Context
from ros_harness import console_script, DOMAIN_ID, stderr_excerpt


def test_help_prints_every_parameter_and_exits_without_starting():
    proc = subprocess.run([console_script('modal_spring_node'), '--help'], capture_output=True,
                          text=True, timeout=30)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith('usage: modal_spring_node [-h] [--managed]\n')
    assert '[--ros-args -p NAME:=VALUE' in proc.stdout
    for name, (default, descriptor) in PARAMETERS.items():
        flag = ', read-only' if descriptor.read_only else ''
        assert f'\n  {name} (default {default!r}{flag})\n' in proc.stdout
        assert descriptor.description.split()[0] in proc.stdout
    assert "  scene (default 'sheet_10x10', read-only)" in proc.stdout
    assert proc.stderr == ''  # nothing started: no log line


def test_an_unknown_option_is_refused_before_anything_starts():
    proc = subprocess.run([console_script('modal_spring_node'), '--manged'], capture_output=True,
                          text=True, timeout=30)
    assert proc.returncode == 2
    assert "unknown arguments ['--manged']" in proc.stderr and '--ros-args -p' in proc.stderr


@pytest.mark.ros
def test_spinning_ends_when_ros_shuts_down_without_waking_the_executor():
    """
    The lost wake-up behind a node hanging on SIGINT.

    rclpy's signal handler shuts the context down below Python (no ``on_shutdown`` callback
    runs) and relies on a guard condition to wake the executor; when that trigger was taken by
    the wait before, ``Executor.spin`` waits forever. Shut a context down that way: the node's
    spin loop must end all the same.
    """
    context = Context()
    rclpy.init(context=context, domain_id=DOMAIN_ID)
    node = rclpy.create_node('spin_probe', context=context)
    executor = PooledExecutor(2, context=context)
    executor.add_node(node)
    spinning = threading.Thread(target=spin_until_stopped, args=(executor,), daemon=True)
    spinning.start()
    time.sleep(0.5)                                   # waiting for work, none comes
    with context.handle:
        context.handle.shutdown()                     # as the signal handler does: no wake
    spinning.join(timeout=10.0)
    assert not spinning.is_alive(), 'the spin loop did not notice that ROS was shut down'
    node.destroy_node()


def _signal_state(pid: int) -> str:
    """Return the signal state of process ``pid`` (shown when a test timed out)."""
    try:
        with open(f'/proc/{pid}/status') as fh:
            return ' '.join(line.strip() for line in fh if line.startswith('Sig'))
    except OSError:
        return 'gone'


def _mapped(pid: int, name: str) -> bool:
    """Whether process ``pid`` has a shared object whose path contains ``name`` loaded."""
    try:
        return name in Path(f'/proc/{pid}/maps').read_text()
    except OSError:
        return False


@pytest.mark.ros
@pytest.mark.parametrize('moment', ['numpy', 'rclpy', 'streaming'])
def test_ctrl_c_while_the_node_starts_ends_it_quietly(moment):
    """
    An interrupt during the imports (numpy's, then rclpy's, extension loading) or once streaming.

    Ends without a traceback. The moments are read from the process itself (what it has
    loaded, what it said), not guessed from a delay a busy machine would stretch.
    """
    proc = subprocess.Popen([console_script('modal_spring_node'), '--ros-args', '-r',
                             '__ns:=/early'], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        if moment == 'streaming':
            while 'streaming' not in proc.stderr.readline():
                assert proc.poll() is None
        else:
            marker = {'numpy': '_multiarray_umath', 'rclpy': '_rclpy_pybind11'}[moment]
            end = time.monotonic() + 60.0
            while not _mapped(proc.pid, marker):
                assert time.monotonic() < end and proc.poll() is None, 'never got there'
                time.sleep(0.001)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=30)
    except BaseException:
        print('the node:', _signal_state(proc.pid))
        proc.kill()
        raise
    assert proc.returncode in (0, EXIT_INTERRUPTED), (proc.returncode, stderr_excerpt(err))
    assert 'Traceback' not in err, stderr_excerpt(err)

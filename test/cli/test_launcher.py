"""Every console script starts in the launcher: a Ctrl-C before ``main`` ends the run quietly."""
from __future__ import annotations

import os
import shlex
import subprocess
import sys
import types

from modal_spring_ros.cli import launcher
from modal_spring_ros.cli.launcher import EXIT_INTERRUPTED

SWALLOWING = """
import os, signal, time
try:                        # as an extension's initialisation or a library's broad except does
    os.kill(os.getpid(), signal.SIGINT)
    time.sleep(1.0)
except BaseException:
    pass


def main():
    print('main ran', [line.split()[1] for line in open('/proc/self/status')
                       if line.startswith(('SigBlk', 'SigIgn', 'SigPnd'))])
    return 0
"""
RUN = ('import sys; from modal_spring_ros.cli.launcher import run_module; '
       'sys.exit(run_module(sys.argv[1]))')


def _run(tmp_path, name: str, source: str, sigint: str = '-') -> subprocess.CompletedProcess:
    """Run module ``name`` in the launcher, from a shell that sets SIGINT (``trap``'s word)."""
    (tmp_path / f'{name}.py').write_text(source)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), *sys.path]))
    command = f'trap {shlex.quote(sigint)} INT; exec "$0" -c "$1" "$2"'
    return subprocess.run(['sh', '-c', command, sys.executable, RUN, name], capture_output=True,
                          text=True, env=env, timeout=60)


def test_a_ctrl_c_swallowed_during_the_imports_still_ends_the_run_before_main(tmp_path):
    done = _run(tmp_path, 'swallowing', SWALLOWING)
    assert done.returncode == EXIT_INTERRUPTED, (done.returncode, done.stderr)
    assert 'main ran' not in done.stdout and 'Traceback' not in done.stderr, done.stdout


def test_without_an_interrupt_main_runs_and_its_status_is_the_run_s(tmp_path):
    done = _run(tmp_path, 'plain', 'def main():\n    print("main ran")\n    return 3\n')
    assert (done.returncode, done.stdout) == (3, 'main ran\n')


def test_an_ignored_sigint_stays_ignored(tmp_path):
    """A shell's background job ignores SIGINT: the launcher keeps it so."""
    done = _run(tmp_path, 'swallowing', SWALLOWING, sigint='')
    assert done.returncode == 0 and done.stdout.startswith('main ran')


CRASHING = """
import ctypes


def main():
    ctypes.string_at(0)      # a crash in native code
"""


def test_a_crash_in_native_code_prints_where_each_thread_was(tmp_path):
    done = _run(tmp_path, 'crashing', CRASHING)
    assert done.returncode == -11, (done.returncode, done.stderr)
    assert 'Fatal Python error: Segmentation fault' in done.stderr
    assert 'crashing.py", line 6 in main' in done.stderr, done.stderr


def test_an_interrupt_python_could_not_raise_during_the_imports_is_not_reported(monkeypatch):
    """
    A Ctrl-C landing in the import system's lock callbacks is "Exception ignored" to Python.

    During the imports it is remembered and answered by the exit status: not reported with a
    traceback; any other unraisable exception still is, and the hook is Python's again after.
    """
    reported = []
    with_hook = launcher._unless_interrupt
    for exc in (KeyboardInterrupt(), ValueError('kept')):
        with_hook(reported.append, types.SimpleNamespace(exc_value=exc))
    assert [type(u.exc_value) for u in reported] == [ValueError]
    before = sys.unraisablehook
    monkeypatch.setattr(launcher.signal, 'signal', lambda *args: None)
    assert launcher.run_module('modal_spring_ros.cli.no_such_module') == launcher.EXIT_MISSING
    assert sys.unraisablehook is before

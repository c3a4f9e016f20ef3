"""
A node started alongside a tool (``--start-node``) that never outlives the tool.

The tool stops its node as Ctrl-C would when it ends (:func:`stop_companion`); a tool that
ends without that chance (killed, crashed) takes the node with it all the same: on Linux the
node is started through a short exec wrapper that asks the kernel for SIGTERM when its parent
ends (``PR_SET_PDEATHSIG``; the wrapper execs the node, so the node is the child and the request
holds). A node left behind would go on publishing into the graph the tool was started for.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys

#: the exec wrapper: SIGTERM on the parent's end, then the node in its place
_DIE_WITH_PARENT = '\n'.join((
    'import ctypes, os, signal, sys',
    'ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)',    # PR_SET_PDEATHSIG
    'if os.getppid() != int(sys.argv[1]):',                           # the parent already gone
    '    sys.exit(0)',
    'os.execv(sys.argv[2], sys.argv[2:])'))


def start_companion(command: list[str]) -> subprocess.Popen:
    """Start ``command`` (a node) to end when this process ends, however it ends (Linux)."""
    if sys.platform.startswith('linux'):
        command = [sys.executable, '-c', _DIE_WITH_PARENT, str(os.getpid()), *command]
    return subprocess.Popen(command)


def stop_companion(process: subprocess.Popen | None, timeout: float = 15.0) -> None:
    """End a companion as Ctrl-C would; kill it if it hangs."""
    if process is None:
        return
    process.send_signal(signal.SIGINT)
    try:
        process.wait(timeout)
    except subprocess.TimeoutExpired:
        process.kill()

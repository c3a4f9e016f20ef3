"""
The fast loop leaves the heavy tests out, and the whole suite keeps them.

``pytest -m "not ros"`` is the developers' fast loop; ``pytest`` alone (CI, ``colcon test``)
runs every test, the slow ones included.
"""
from __future__ import annotations

import os
import subprocess
import sys

from helpers import REPO
import pytest


def _collected(*args: str) -> set[str]:
    """
    Return the test ids pytest collects with ``args``.

    Without the options of the pytest running this test: ``colcon test`` passes its own
    (``-q``, ``--junit-xml``) in ``PYTEST_ADDOPTS``.
    """
    env = {k: v for k, v in os.environ.items() if k != 'PYTEST_ADDOPTS'}
    proc = subprocess.run([sys.executable, '-m', 'pytest', '--collect-only', '-q',
                           '-p', 'no:cacheprovider', *args], cwd=REPO, capture_output=True,
                          text=True, timeout=120, env=env)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return {line for line in proc.stdout.splitlines() if '::' in line}


@pytest.mark.slow
def test_a_marker_expression_without_slow_leaves_the_slow_tests_out():
    everything = _collected()
    fast = _collected('-m', 'not ros')
    slow = _collected('-m', 'slow')
    with_slow = _collected('-m', 'not ros', '--runslow')
    assert slow and slow < everything
    assert not fast & slow                           # the fast loop has no slow test
    assert fast < with_slow and with_slow - fast <= slow and with_slow - fast
    assert fast | slow | _collected('-m', 'ros') == everything   # nothing is lost to `pytest`

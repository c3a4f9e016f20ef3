"""
The fast loop leaves the heavy tests out, and the whole suite keeps them.

``pytest -m "not ros"`` is the developers' fast loop; ``pytest`` alone (CI, ``colcon test``)
runs every test, the slow ones included.
"""
from __future__ import annotations

import os
from pathlib import Path
import subprocess
import sys
import types

import conftest
from helpers import REPO
import pytest


def _collected(*args: str) -> dict[str, set[str]]:
    """
    Return the test ids pytest collects with ``args``, each with its ``ros``/``slow`` markers.

    Without the options of the pytest running this test: ``colcon test`` passes its own
    (``-q``, ``--junit-xml``) in ``PYTEST_ADDOPTS``.
    """
    env = {k: v for k, v in os.environ.items() if k != 'PYTEST_ADDOPTS'}
    env['PYTHONPATH'] = os.pathsep.join(filter(None, [str(Path(__file__).parent),
                                                      env.get('PYTHONPATH', '')]))
    proc = subprocess.run([sys.executable, '-m', 'pytest', '--collect-only', '-q',
                           '-p', 'no:cacheprovider', '-p', 'marker_listing', *args], cwd=REPO,
                          capture_output=True, text=True, timeout=120, env=env)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    found = {}
    for line in proc.stdout.splitlines():
        if line.startswith('MARKED '):
            nodeid, marks = line[len('MARKED '):].rsplit(' ', 1)   # ids may hold spaces
            found[nodeid] = set(filter(None, marks.split(',')))
    return found


@pytest.mark.slow
def test_a_marker_expression_without_slow_leaves_the_slow_tests_out():
    """The fast loop is every test but the ros and slow ones: none lost, none slow."""
    everything = _collected()
    slow = {t for t, marks in everything.items() if 'slow' in marks}
    ros = {t for t, marks in everything.items() if 'ros' in marks}
    fast = set(_collected('-m', 'not ros'))
    assert slow and ros and slow < set(everything)
    assert fast == set(everything) - ros - slow


@pytest.mark.parametrize('expression, runslow, left_out', [
    ('', False, False),                 # pytest alone: everything
    ('not ros', False, True),           # the fast loop
    ('not ros', True, False),           # --runslow adds them back
    ('slow', False, False),             # named: kept
    ('not slow', False, False),         # named: the expression decides
])
def test_only_an_expression_that_does_not_name_slow_leaves_them_out(expression, runslow,
                                                                    left_out):
    config = types.SimpleNamespace(option=types.SimpleNamespace(markexpr=expression),
                                   getoption=lambda name: runslow)
    assert conftest._leaves_slow_out(config) is left_out

"""Fixtures shared by the suite (helpers they use live in ``helpers.py``)."""
from __future__ import annotations

import os
from pathlib import Path
import shutil
import signal
import sys
import tempfile
import threading

from helpers import variant
from modal_spring_ros.core.bases.basis import ModalBasis
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.threads import blas_threads
from modal_spring_ros.scenes.resources import load_scene
import pytest
from threadpoolctl import threadpool_limits

# Spring samples are cached per run of the suite, never in the user's cache folder (the
# node's processes inherit it).
os.environ['MODAL_SPRING_ROS_CACHE'] = tempfile.mkdtemp(prefix='modal_spring_samples_')

# A suite started as a shell's background job (``pytest &`` in a script, nohup) has SIGINT
# ignored, and every process it starts would inherit that: the tests that press Ctrl-C at a
# node still importing would find it deaf. The suite interrupts as a terminal does.
if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


#: the folder of the node's tests (all over DDS, or on the node's threads)
ROS_TESTS = Path(__file__).parent / 'ros'
#: pytest-xdist's group of the tests that run nodes over DDS
DDS_GROUP = 'dds'


def pytest_addoption(parser):
    parser.addoption('--runslow', action='store_true',
                     help='run the tests marked slow even when -m does not name them')


def _leaves_slow_out(config) -> bool:
    """Tell whether a marker expression was given that does not name ``slow`` (nor --runslow)."""
    expression = config.option.markexpr or ''
    return (bool(expression.strip()) and 'slow' not in expression
            and not config.getoption('--runslow'))


def pytest_report_header(config):
    if _leaves_slow_out(config):
        return 'tests marked slow left out (-m does not name them): add --runslow to run them'
    return None


def _uses_dds(item) -> bool:
    """Tell whether a test runs nodes over DDS (marked ``ros``, or in ``test/ros``)."""
    return item.get_closest_marker('ros') is not None or ROS_TESTS in item.path.parents


@pytest.hookimpl(tryfirst=True)     # before pytest-xdist names the groups in the test ids
def pytest_collection_modifyitems(config, items):
    """
    Keep the DDS tests on one worker, and leave the ``slow`` ones out where ``-m`` says so.

    With ``-n 2 --dist loadgroup`` (the README's test command) every test that runs nodes over
    DDS is in one group, run in turn by one worker, as a serial run would: their timings and
    their one DDS domain are never shared with another test's nodes, while the other worker runs
    the tests without DDS beside them (xdist hands out the largest unit, the group, first).

    Without ``-m`` every test runs (CI, on both cores; ``colcon test``); ``-m "not ros"`` is the
    fast loop; ``-m "not ros" --runslow`` adds the slow ones, ``-m slow`` runs only them.
    """
    for item in items:
        if _uses_dds(item):
            item.add_marker(pytest.mark.xdist_group(DDS_GROUP))
    if not _leaves_slow_out(config):
        return
    slow = [item for item in items if item.get_closest_marker('slow') is not None]
    if slow:
        config.hook.pytest_deselected(items=slow)
        items[:] = [item for item in items if item.get_closest_marker('slow') is None]


@pytest.fixture(scope='session')
def sheet_undamped_still():
    """sheet_10x10 without damping and without anchor motion (a conservative system)."""
    scene = variant('sheet_10x10', damping={'ratio': 0.0}, anchor_motion=[])
    model = MassSpringModel(scene)
    return model, ModalBasis(model)


@pytest.fixture(scope='session')
def sheet_10x10():
    model = MassSpringModel(load_scene('sheet_10x10'))
    return model, ModalBasis(model)


@pytest.fixture
def two_blas_threads():
    """Set the library at two threads (its default on a 2-core machine), whatever the machine."""
    with threadpool_limits(2, user_api='blas'):
        assert blas_threads() == 2
        yield


def pytest_sessionfinish(session, exitstatus):
    """
    End ROS before the interpreter ends, and remove this session's sample cache.

    An rclpy context or executor thread still alive at exit makes the C++ runtime abort the
    interpreter (``terminate called without an active exception``, exit -6), which colcon test
    reports as a failure whatever the tests said: shut the default context down if a test left
    it initialised, and say which threads were left running.
    """
    if 'rclpy' in sys.modules:
        sys.modules['rclpy'].try_shutdown()
    shutil.rmtree(os.environ['MODAL_SPRING_ROS_CACHE'], ignore_errors=True)
    left = [t.name for t in threading.enumerate()
            if t is not threading.main_thread() and t.is_alive() and not t.daemon]
    if left:
        print(f'\nthreads left running at the end of the session: {", ".join(left)}',
              file=sys.stderr)

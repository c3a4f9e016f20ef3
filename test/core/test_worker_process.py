"""The worker process that runs sparse mode computations outside the node's interpreter."""
from __future__ import annotations

import os
import signal
import threading
import time

from modal_spring_ros.core.bases.basis import ModalBasis
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.threads import blas_threads
from modal_spring_ros.core.worker import (MAX_NICENESS, WORKER_NICENESS, WORKER_THREADS,
                                          WorkerError, WorkerProcess)
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest


def _raise_value_error(text: str) -> None:
    raise ValueError(text)


def test_calls_run_in_one_reused_child_and_its_errors_are_raised_here():
    with WorkerProcess() as worker:
        child = worker.call(os.getpid)
        assert child != os.getpid()
        assert worker.call(os.getpid) == child           # the same child, kept
        assert worker.call(divmod, 17, 5) == (3, 2)
        with pytest.raises(ValueError, match='named problem'):
            worker.call(_raise_value_error, 'named problem')
        assert worker.call(os.getpid) == child           # an error does not end it


def test_a_child_that_dies_is_reported_and_replaced():
    with WorkerProcess() as worker:
        child = worker.call(os.getpid)
        with pytest.raises(WorkerError, match=r'killed \(SIGKILL: out of memory\?\)'):
            worker.call(os.kill, child, signal.SIGKILL)
        assert worker.call(os.getpid) not in (child, os.getpid())
        child = worker.call(os.getpid)
        with pytest.raises(WorkerError, match='killed by SIGSEGV'):
            worker.call(os.kill, child, signal.SIGSEGV)


def _niceness() -> int:
    return os.getpriority(os.PRIO_PROCESS, 0)


def test_the_child_runs_at_its_parents_priority_until_it_gives_way_then_below_it():
    """
    Nothing streams yet: the child's work is what a user waits for, at the parent's priority.

    Once the parent streams, the child's long work gives way to it: ``WORKER_NICENESS`` below
    the parent, a call under way included, and a child started after (a crash) starts below.
    """
    own = _niceness()
    below = min(own + WORKER_NICENESS, MAX_NICENESS)
    assert below > own, 'this test needs a process that can be lowered'
    with WorkerProcess() as worker:
        child = worker.call(os.getpid)
        assert worker.call(_niceness) == own
        answers = []
        caller = threading.Thread(target=lambda: answers.append(worker.call(
            _sleep_then_niceness, 1.0)))
        caller.start()
        time.sleep(0.3)
        worker.give_way()                      # while a call runs: that call gives way too
        caller.join(timeout=120.0)
        assert answers == [below] and worker.call(_niceness) == below
        assert worker.call(os.getpid) == child
        with pytest.raises(WorkerError, match='SIGKILL'):
            worker.call(os.kill, child, signal.SIGKILL)
        assert worker.call(os.getpid) != child and worker.call(_niceness) == below
    assert _niceness() == own                  # the parent's own priority untouched


def _sleep_then_niceness(seconds: float) -> int:
    time.sleep(seconds)
    return _niceness()


def _sleep_and_count_threads(seconds: float) -> int:
    time.sleep(seconds)
    return blas_threads()


def test_the_groups_stop_signals_leave_the_child_to_its_parent_and_it_runs_on_one_thread():
    """Ctrl-C, ``timeout`` or a service manager signal the group: the call still answers."""
    with WorkerProcess() as worker:
        child = worker.call(os.getpid)
        answers = []
        caller = threading.Thread(
            target=lambda: answers.append(worker.call(_sleep_and_count_threads, 1.0)))
        caller.start()
        time.sleep(0.3)
        os.kill(child, signal.SIGTERM)
        os.kill(child, signal.SIGINT)
        caller.join(timeout=120.0)     # beside busy processes it can be slow
        assert answers == [WORKER_THREADS] and worker.call(os.getpid) == child


def test_close_ends_a_call_in_progress_and_refuses_new_ones():
    worker = WorkerProcess()
    worker.call(os.getpid)
    errors = []

    def long_call():
        try:
            worker.call(time.sleep, 60.0)
        except WorkerError as exc:
            errors.append(str(exc))

    caller = threading.Thread(target=long_call)
    caller.start()
    time.sleep(0.5)
    worker.close()
    caller.join(timeout=10.0)
    assert not caller.is_alive() and errors and 'closed' in errors[0]
    with pytest.raises(WorkerError, match='closed'):
        worker.call(os.getpid)


def test_modes_computed_in_the_worker_are_bit_identical_and_grow_the_same_way():
    model = MassSpringModel(load_scene('sheet_32x32'))
    here = ModalBasis(model, initial_modes=12)
    with WorkerProcess() as worker:
        there = ModalBasis(model, initial_modes=12, worker=worker)
        assert not there.dense
        np.testing.assert_array_equal(there.omega, here.omega)
        np.testing.assert_array_equal(there.vectors, here.vectors)
        here.ensure_count(40)
        there.ensure_count(40)                           # on the factor kept in the child
        np.testing.assert_array_equal(there.omega, here.omega)
        np.testing.assert_array_equal(there.vectors, here.vectors)


def test_a_cancelled_call_ends_its_child_and_the_next_call_gets_a_new_one():
    cancel = threading.Event()
    with WorkerProcess(cancelled=cancel.is_set) as worker:
        child = worker.call(os.getpid)
        threading.Timer(0.3, cancel.set).start()
        with pytest.raises(WorkerError, match='cancelled'):
            worker.call(time.sleep, 60.0)
        cancel.clear()
        assert worker.call(os.getpid) not in (child, os.getpid())


@pytest.mark.slow
def test_springs_sampled_in_the_worker_are_the_same_sample():
    from modal_spring_ros.core.config import SimulationConfig
    from modal_spring_ros.core.factory import build_simulation
    from modal_spring_ros.core.filter_band import FilterBand
    scene = load_scene('sheet_32x32')
    config = SimulationConfig(band=FilterBand('lowpass', 0, 15, 'index'), forces='sampled',
                              basis='rest')
    here = build_simulation(scene, config)._forces.sample      # no sample store: trained
    with WorkerProcess() as worker:
        messages = []
        there = build_simulation(scene, config, progress=messages.append,
                                 worker=worker)._forces.sample
    assert any('in a worker process' in m for m in messages)
    np.testing.assert_array_equal(there.springs, here.springs)
    np.testing.assert_array_equal(there.weights, here.weights)
    assert there.held_out_error == here.held_out_error < 0.01

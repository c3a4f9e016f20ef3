"""Per-step linear algebra runs on one BLAS thread, and the library's setting comes back after."""
from __future__ import annotations

import threading

from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.forces import ForceOptions
from modal_spring_ros.core.forces import sampling
from modal_spring_ros.core.simulations import FullSimulation, ModalSettings, ModalSimulation
from modal_spring_ros.core.threads import (blas_threads, process_threads, STEP_THREADS,
                                           stepping_threads)
import numpy as np
from threadpoolctl import OpenBLASController, threadpool_limits, ThreadpoolController


def test_holders_nest_and_overlap_and_the_setting_comes_back_after_the_last(two_blas_threads):
    """As in the node: the simulation thread holds it for its life, a training overlaps."""
    entered, leave = threading.Event(), threading.Event()
    seen = []

    def training():
        with stepping_threads():
            seen.append(blas_threads())
            entered.set()
            leave.wait(10)
        seen.append(blas_threads())             # left while the other still holds it
    with stepping_threads():
        assert blas_threads() == STEP_THREADS == 1
        with stepping_threads():
            assert blas_threads() == 1
        assert blas_threads() == 1              # the inner one leaving keeps the outer's
        thread = threading.Thread(target=training)
        thread.start()
        assert entered.wait(10)
        leave.set()
        thread.join(10)
        assert seen == [1, 1] and blas_threads() == 1
    assert blas_threads() == 2                  # the last holder gone: the library's setting


def test_steps_of_every_simulation_and_the_spring_training_run_on_one_thread(
        two_blas_threads, sheet_10x10, monkeypatch):
    model, basis = sheet_10x10
    seen = []
    for sim in (FullSimulation(model, dt=2e-4, basis=basis),
                ModalSimulation(model, basis, FilterBand(),
                                ModalSettings(dt=2e-4, basis_kind='rest'))):
        step_once = sim._step_once

        def counted(step_once=step_once):
            seen.append(blas_threads())
            step_once()
        monkeypatch.setattr(sim, '_step_once', counted)
        sim.step(3)
        assert np.isfinite(sim.positions()).all()
    nnls = sampling.scipy.optimize.nnls

    def counted_nnls(*args, **kwargs):
        seen.append(blas_threads())
        return nnls(*args, **kwargs)
    monkeypatch.setattr(sampling.scipy.optimize, 'nnls', counted_nnls)
    ModalSimulation(model, basis, FilterBand('lowpass', 0, 5, 'index'),
                    ModalSettings(dt=2e-4, basis_kind='rest',
                                  forces=ForceOptions('sampled', tolerance=0.05)))
    assert len(seen) > 6 and set(seen) == {1}
    assert blas_threads() == 2


def test_the_process_limit_is_the_stepping_one_so_steps_inside_it_nest(two_blas_threads):
    with process_threads({}):
        assert blas_threads() == 1
        with stepping_threads():
            assert blas_threads() == 1
        assert blas_threads() == 1              # a run's loop leaving keeps the script's
    with process_threads({'OMP_NUM_THREADS': '2'}):
        assert blas_threads() == 2
        with stepping_threads():
            assert blas_threads() == 1          # steps on one, whatever the user set
        assert blas_threads() == 2
    assert blas_threads() == 2


def test_a_library_already_on_one_thread_is_left_alone_and_one_on_two_set_and_set_back(
        two_blas_threads, monkeypatch):
    """A step taken one at a time switches each library once each way, or not at all."""
    calls = []
    real = OpenBLASController.set_num_threads

    def counted(self, count):
        calls.append(count)
        return real(self, count)
    monkeypatch.setattr(OpenBLASController, 'set_num_threads', counted)
    with stepping_threads():
        assert blas_threads() == 1
    libraries = len(ThreadpoolController().select(user_api='blas').lib_controllers)
    assert libraries >= 1 and calls == [1] * libraries + [2] * libraries
    assert blas_threads() == 2
    with threadpool_limits(1, user_api='blas'):     # a user's OPENBLAS_NUM_THREADS=1
        calls.clear()
        with stepping_threads():
            assert blas_threads() == 1
        assert calls == [] and blas_threads() == 1

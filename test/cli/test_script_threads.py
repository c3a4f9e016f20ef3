"""The console scripts run numpy's linear algebra on one thread, unless the user names a count."""
from __future__ import annotations

import os

from modal_spring_ros.cli.common import run_main
from modal_spring_ros.core.threads import blas_threads, THREAD_VARIABLES, threads_set_by
import pytest


@pytest.mark.parametrize('variable', THREAD_VARIABLES)
def test_a_console_script_runs_on_one_thread_unless_its_environment_names_a_count(
        two_blas_threads, monkeypatch, variable):
    """A run's set-up is CPU a user pays: one thread, but a count the user set is kept."""
    for name in THREAD_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    assert threads_set_by(os.environ) is None
    assert run_main('modal_spring_sim', blas_threads) == 1
    assert blas_threads() == 2                  # the library's setting back after the script
    monkeypatch.setenv(variable, '2')
    assert threads_set_by(os.environ) == variable
    assert run_main('modal_spring_sim', blas_threads) == 2
    monkeypatch.setenv(variable, ' ')           # set but blank: names no count
    assert run_main('modal_spring_sim', blas_threads) == 1

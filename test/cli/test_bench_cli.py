"""``modal_spring_bench`` as a user runs it: what it refuses, and a suite stopped by SIGTERM."""
from __future__ import annotations

import os
import signal
import subprocess
import time

from helpers import process_group
from modal_spring_ros.cli.modal_spring_bench import main
import pytest
from ros_harness import console_script


@pytest.mark.parametrize('argv, message', [
    (['--suite', 'stream', '--case', 'nothing'], "--case 'nothing' matches no stream case"),
    (['--suite', 'steps', '--case', '100k'], '--case picks stream cases'),
    (['--suite', 'promise_demanding', '--seeds', '9'], '--seeds: '),
    (['--suite', 'promise', '--seeds', '1'], '--seeds picks promise_demanding seeds'),
])
def test_a_case_or_seed_that_cannot_be_run_is_refused_before_any_work(argv, message, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2 and message in capsys.readouterr().err


@pytest.mark.slow
def test_sigterm_ends_a_suite_and_its_worker_processes(tmp_path):
    """The promise suite measures in two worker processes: none outlives the command."""
    proc = subprocess.Popen([console_script('modal_spring_bench'), '--suite', 'promise',
                             '--quick', '--out', str(tmp_path)], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        deadline = time.monotonic() + 60.0
        while len(process_group(proc.pid, 0.0)) < 3 and time.monotonic() < deadline:
            time.sleep(0.1)       # the command and its two workers
        assert len(process_group(proc.pid, 0.0)) >= 3
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(30) == 128 + signal.SIGTERM
        assert process_group(proc.pid, 10.0) == []
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass

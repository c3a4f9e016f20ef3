"""Busy processes beside a benchmark: they burn CPU while their block runs, and end with it."""
from __future__ import annotations

import os
import time

from modal_spring_ros.bench.costs.busy_load import BusyLoad
from modal_spring_ros.bench.costs.process_cpu import tree_cpu_seconds
import pytest


@pytest.mark.skipif(not os.path.isdir('/proc/self'), reason='reads /proc (Linux)')
def test_busy_processes_burn_cpu_while_the_block_runs_and_are_gone_after():
    with BusyLoad(2) as load:
        pids = [p.pid for p in load.processes]
        time.sleep(2.5)
        burnt = [tree_cpu_seconds(pid) for pid in pids]
    # each spins without waiting: a tenth of the time even where six spinning processes share
    # two cores (0.2 s of 1 s was seen there; one that started and idled burns about 0.05 s)
    assert len(pids) == 2 and all(cpu is not None and cpu > 0.25 for cpu in burnt), burnt
    assert all(tree_cpu_seconds(pid) is None for pid in pids)      # killed and reaped
    assert load.processes == []


@pytest.mark.parametrize('count', [-1, 1.5, '2'])
def test_a_count_that_is_not_a_whole_number_is_refused(count):
    with pytest.raises(ValueError, match='must be a whole number, at least 0'):
        BusyLoad(count)

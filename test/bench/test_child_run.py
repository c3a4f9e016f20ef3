"""A benchmark case in its own process: its answer, its progress, and its end always known."""
from __future__ import annotations

import math
import multiprocessing as mp
import os

from modal_spring_ros.bench.child_run import ChildFailed, in_child, pooled
import pytest


def counted(n: int, progress) -> int:
    """Report ``n`` steps, then return their sum."""
    for k in range(n):
        progress(f'step {k}')
    return sum(range(n))


def test_a_child_s_answer_and_progress_reach_the_caller_in_order():
    seen = []
    assert in_child(counted, 4, progress=seen.append) == 6
    assert seen == ['step 0', 'step 1', 'step 2', 'step 3']
    assert in_child(math.hypot, 3.0, 4.0) == 5.0


def test_a_child_that_raises_is_named_with_its_exception():
    with pytest.raises(ChildFailed, match=r'^sqrt case: ValueError: math domain error'):
        in_child(math.sqrt, -1.0, what='sqrt case')


@pytest.mark.parametrize('end, said', [(os._exit, 'exit status 3'),
                                       (os.abort, 'killed by SIGABRT')])
def test_a_child_that_dies_without_an_answer_is_an_error_not_a_wait(end, said):
    with pytest.raises(ChildFailed, match=f'ended without an answer \\({said}\\)'):
        in_child(end, *((3,) if end is os._exit else ()))


def test_a_pool_yields_each_answer_and_a_worker_s_death_is_an_error_not_a_wait():
    with mp.get_context('spawn').Pool(2) as pool:
        assert sorted(pooled(pool, math.sqrt, [4.0, 9.0, 16.0], 'roots')) == [2.0, 3.0, 4.0]
        with pytest.raises(ChildFailed, match='^exits: a worker process ended without an answer'):
            list(pooled(pool, os._exit, [3], 'exits'))

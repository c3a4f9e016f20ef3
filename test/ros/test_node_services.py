"""
The node's ``~/pause`` and ``~/reset`` services answer requests sent together, together.

The node runs in this process (its own context, spun as ``modal_spring_node`` spins it), so its
simulation thread's queue can be held: requests then wait for their answers side by side, and
none is held back until the one before it is answered or times out.
"""
from __future__ import annotations

import threading
import time

from modal_spring_ros.ros.changes.requests import Pause, Reset
from modal_spring_ros.ros.changes.run_services import SERVICE_TIMEOUT_S
import pytest
from ros_harness import Client, node_in_process, wait_for
from std_srvs.srv import SetBool, Trigger

pytestmark = pytest.mark.ros

TOGETHER = 6


class HeldQueue:
    """Stands in for the simulation thread's queue: answers nothing until ``count`` are held."""

    def __init__(self, count: int, timeout: float):
        self.count, self.timeout = count, timeout
        self.held: list = []
        self.most_held = 0
        self._lock = threading.Lock()
        self._full = threading.Event()
        threading.Thread(target=self._answer, daemon=True).start()

    def submit(self, request) -> None:
        with self._lock:
            self.held.append(request)
            self.most_held = max(self.most_held, len(self.held))
            if len(self.held) >= self.count:
                self._full.set()

    def _answer(self) -> None:
        self._full.wait(self.timeout)
        with self._lock:
            held, self.held = self.held, []
        for request in held:
            request.finish(True, f'{type(request).__name__.lower()} applied')


@pytest.fixture
def together():
    with node_in_process('together') as node:
        yield node


def test_pause_and_reset_requests_sent_together_wait_side_by_side(together):
    node = together
    client = Client('together_client')
    try:
        # matched, and answered by the real simulation thread
        assert client.call(SetBool, '/together/modal_spring/pause',
                           SetBool.Request(data=False)).success
        assert client.call(Trigger, '/together/modal_spring/reset', Trigger.Request()).success
        queue = HeldQueue(TOGETHER, timeout=3 * SERVICE_TIMEOUT_S)
        node._thread.submit = queue.submit
        pause = client.node.create_client(SetBool, '/together/modal_spring/pause')
        reset = client.node.create_client(Trigger, '/together/modal_spring/reset')
        assert pause.wait_for_service(10.0) and reset.wait_for_service(10.0)
        futures = [pause.call_async(SetBool.Request(data=k % 2 == 0)) if k % 2 else
                   reset.call_async(Trigger.Request()) for k in range(TOGETHER)]
        assert wait_for(lambda: all(f.done() for f in futures), 4 * SERVICE_TIMEOUT_S)
        # every request reached the queue before the first was answered
        assert queue.most_held == TOGETHER
        answers = [f.result() for f in futures]
        assert all(a.success for a in answers), [a.message for a in answers]
        assert sorted(a.message for a in answers) == (
            ['pause applied'] * (TOGETHER // 2) + ['reset applied'] * (TOGETHER // 2))
    finally:
        client.close()


def test_a_request_the_simulation_never_answers_times_out_with_a_reason(together):
    node = together
    client = Client('silent_client')
    try:
        assert client.call(Trigger, '/together/modal_spring/reset', Trigger.Request()).success
        held = []
        node._thread.submit = held.append                     # never answered
        sent = time.monotonic()
        answer = client.call(SetBool, '/together/modal_spring/pause',
                             SetBool.Request(data=True), timeout=4 * SERVICE_TIMEOUT_S)
        assert time.monotonic() - sent >= SERVICE_TIMEOUT_S
        assert not answer.success and answer.message.startswith('not applied in time')
        assert [type(r) for r in held] == [Pause]
        # the service is free again: the next request is answered by the simulation
        del node._thread.submit
        assert client.call(Trigger, '/together/modal_spring/reset', Trigger.Request()).success
        assert Reset not in [type(r) for r in held]
    finally:
        client.close()

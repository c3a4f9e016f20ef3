"""Slow parameter changes off the service thread: answered at once, superseded, reverted."""
from __future__ import annotations

import contextlib
import threading
import time

from modal_spring_ros.ros.changes.change_preparer import ChangePreparer, ChangeRefused
import pytest


class Recorder:
    """prepare / commit / revert that record their calls; ``gate`` holds prepare until set."""

    def __init__(self, refuse: str = '', gate: threading.Event | None = None):
        self.refuse = refuse
        self.gate = gate
        self.prepared: list[dict] = []
        self.committed: list[dict] = []
        self.reverted: list[tuple[dict, str]] = []
        self.entered = threading.Event()

    def prepare(self, incoming):
        self.prepared.append(dict(incoming))
        self.entered.set()
        if self.gate is not None:
            assert self.gate.wait(20.0)
        if self.refuse:
            raise ChangeRefused(self.refuse)
        return ('plan', dict(incoming))

    def commit(self, incoming, prepared):
        assert prepared == ('plan', incoming)
        self.committed.append(dict(incoming))

    def revert(self, incoming, reason):
        self.reverted.append((dict(incoming), reason))


def preparer(recorder: Recorder, answer_within_s: float = 0.5) -> ChangePreparer:
    return ChangePreparer(recorder.prepare, recorder.commit, recorder.revert,
                          answer_within_s=answer_within_s)


def ask(p: ChangePreparer, incoming: dict) -> tuple[bool, str]:
    """Request ``incoming`` as the node does: its parameters are set once it is accepted."""
    accepted, reason = p.request(incoming)
    if accepted:
        p.parameters_set()
    return accepted, reason


@contextlib.contextmanager
def gated(answer_within_s: float, refuse: str = ''):
    """Return a gate holding every preparation, its recorder and the preparer; stop it after."""
    gate = threading.Event()
    rec = Recorder(refuse=refuse, gate=gate)
    p = preparer(rec, answer_within_s)
    try:
        yield gate, rec, p
    finally:
        gate.set()
        p.stop()


def test_a_quick_change_is_answered_with_its_outcome_and_committed_once_it_is_set():
    rec = Recorder()
    p = preparer(rec, answer_within_s=10.0)
    try:
        assert p.request({'filter.high_hz': 7.0}) == (True, '')
        assert rec.prepared == [{'filter.high_hz': 7.0}]       # prepared before the answer
        assert not p.wait_idle(0.3) and rec.committed == []    # not before the set
        p.parameters_set()
        assert p.wait_idle(5.0) and not p.busy
        assert rec.committed == [{'filter.high_hz': 7.0}]
    finally:
        p.stop()


def test_a_change_whose_parameters_are_never_set_is_dropped_and_reported(monkeypatch):
    monkeypatch.setattr('modal_spring_ros.ros.changes.change_preparer.SET_WITHIN_S', 0.3)
    rec = Recorder()
    p = preparer(rec, answer_within_s=10.0)
    try:
        assert p.request({'filter.high_hz': 7.0}) == (True, '')     # and no set follows
        assert p.wait_idle(5.0)
        assert rec.committed == []
        assert rec.reverted == [({'filter.high_hz': 7.0},
                                 'its parameters were not set within 0.3 s')]
        assert 'filter.high_hz=7.0 dropped: its parameters were not set' in p.state().reverted
        assert ask(p, {'filter.high_hz': 8.0}) == (True, '')        # the next one goes on
        assert p.wait_idle(5.0) and rec.committed == [{'filter.high_hz': 8.0}]
    finally:
        p.stop()


def test_a_request_refused_after_it_was_accepted_is_dropped_when_the_next_one_comes():
    """The services take one request at a time: a new one means the last was never set."""
    rec = Recorder()
    p = preparer(rec, answer_within_s=10.0)
    try:
        assert p.request({'filter.high_hz': 7.0}) == (True, '')     # then refused elsewhere
        assert ask(p, {'filter.high_hz': 8.0})[0]
        assert p.wait_idle(5.0)
        assert rec.committed == [{'filter.high_hz': 8.0}]
        (incoming, reason), = rec.reverted
        assert incoming == {'filter.high_hz': 7.0} and reason.startswith('refused after')
    finally:
        p.stop()


def test_a_quick_refusal_is_answered_as_one_and_changes_nothing():
    rec = Recorder(refuse='sim.dt (0.01 s) is at or above the explicit stability limit')
    p = preparer(rec, answer_within_s=10.0)
    try:
        accepted, reason = ask(p, {'sim.dt': 0.01})
        assert not accepted and 'stability limit' in reason
        assert rec.committed == [] and rec.reverted == []
        assert p.state().reverted == ''
    finally:
        p.stop()


def test_a_slow_change_is_answered_pending_then_committed():
    with gated(0.2) as (gate, rec, p):
        start = time.monotonic()
        accepted, reason = ask(p, {'filter.high_hz': 50.0})
        assert accepted and reason.startswith('pending: preparing')
        assert time.monotonic() - start < 5.0
        assert p.busy and 'filter.high_hz=50.0' in p.state().preparing
        assert rec.committed == []
        gate.set()
        assert p.wait_idle(10.0)
        assert rec.committed == [{'filter.high_hz': 50.0}] and p.state().preparing == ''


def test_a_storm_is_answered_as_it_comes_and_only_the_latest_is_prepared():
    with gated(0.2) as (gate, rec, p):
        latencies, answers = [], []
        for k in range(50):                      # 50 band changes a second, for a second
            start = time.monotonic()
            answers.append(ask(p, {'filter.high_hz': float(k), 'filter.type': 'lowpass'}))
            latencies.append(time.monotonic() - start)
            time.sleep(0.02)
        assert all(accepted for accepted, _ in answers)
        # the first waits for its answer at most answer_within_s; every later one is queued
        assert max(latencies) < 1.0, max(latencies)
        assert all(reason.startswith('pending: queued') for _, reason in answers[1:])
        gate.set()
        assert p.wait_idle(10.0)
        # the one being prepared, then the pending one holding the newest values
        assert rec.prepared == [{'filter.high_hz': 0.0, 'filter.type': 'lowpass'},
                                {'filter.high_hz': 49.0, 'filter.type': 'lowpass'}]
        assert rec.committed == rec.prepared


def test_a_change_failing_after_its_answer_is_reverted_and_reported():
    refuse = 'sim.dt (0.0005 s) is at or above the explicit stability limit'
    with gated(0.1, refuse) as (gate, rec, p):
        accepted, reason = ask(p, {'filter.type': 'allpass'})
        assert accepted and reason.startswith('pending')
        gate.set()
        assert p.wait_idle(10.0)
        assert rec.committed == []
        assert rec.reverted == [({'filter.type': 'allpass'}, rec.refuse)]
        reverted = p.state().reverted
        assert "filter.type='allpass' reverted" in reverted and 'stability limit' in reverted


def test_stopping_abandons_a_change_being_prepared():
    gate = threading.Event()
    rec = Recorder(gate=gate)
    p = preparer(rec, answer_within_s=0.1)
    ask(p, {'filter.high_hz': 5.0})
    assert rec.entered.wait(5.0)
    stopper = threading.Thread(target=p.stop)
    stopper.start()
    time.sleep(0.1)
    gate.set()
    stopper.join(10.0)
    assert rec.committed == [] and rec.reverted == []
    assert p.request({'filter.high_hz': 6.0}) == (False, 'the node is shutting down')


def test_a_change_failing_once_stopping_was_said_is_neither_reverted_nor_committed():
    """The node closes the worker a change waits on after saying it stops: no false ERROR."""
    gate = threading.Event()
    rec = Recorder(refuse='modal_spring_modes ended during the call (closed)', gate=gate)
    p = preparer(rec, answer_within_s=0.1)
    assert ask(p, {'modal.forces': 'sampled'})[0]        # answered as pending
    assert rec.entered.wait(5.0)
    p.stopping()
    gate.set()                                            # the worker closed: the call fails
    p.stop()
    assert rec.reverted == [] and rec.committed == []
    assert p.state().reverted == ''


@pytest.mark.parametrize('failure', [RuntimeError('a bug'), ZeroDivisionError()])
def test_an_unexpected_failure_is_a_refusal_and_the_preparer_goes_on(failure):
    calls = []

    def prepare(incoming):
        calls.append(incoming)
        if len(calls) == 1:
            raise failure
        return ('plan', incoming)
    committed = []
    p = ChangePreparer(prepare, lambda i, plan: committed.append(i), lambda i, r: None,
                       answer_within_s=10.0)
    try:
        accepted, reason = ask(p, {'method': 'full'})
        assert not accepted and reason.startswith('could not prepare the change')
        assert ask(p, {'method': 'modal'}) == (True, '')
        assert p.wait_idle(5.0) and committed == [{'method': 'modal'}]
    finally:
        p.stop()

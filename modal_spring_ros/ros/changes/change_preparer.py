"""
Parameter changes that take long, prepared off the parameter services' thread.

A band that needs new modes on a large scene, sampled springs to train, a new simulation to
build: any of these can take seconds to minutes, and a parameter service that waits for them
leaves every other request behind it unanswered (clients time out). So the node's parameter
callback only validates a request (cheap: values, ranges, the band's edges) and hands the slow
part to one :class:`ChangePreparer` thread:

- when nothing is being prepared, the callback waits at most ``answer_within_s`` for the
  outcome: a change prepared in that time is answered with its real result (refused with its
  reason, and then nothing has changed);
- a longer one is answered as accepted and *pending*; ``/diagnostics`` says what is being
  prepared until the run has it;
- a request arriving while a change is being prepared joins the one pending after it (a newer
  value of a parameter supersedes the pending one, other parameters add to it) and is answered
  at once: a storm of band changes is answered as fast as it comes, and only the latest is built;
- a pending change that fails after its answer is *reverted*: the parameters it set that nothing
  newer has set since go back to the values the run has, with an ERROR in the log and a warning
  on ``/diagnostics``;
- a prepared change is *committed* (handed to the run) only once the parameters of every request
  it holds are set: the node's on-set callback only validates and prepares, and its post-set
  callback says :meth:`ChangePreparer.parameters_set` (rclcpp's rule for on-set callbacks: no
  side effect, since a later callback or the set itself may still refuse the change). The
  parameter services take one request at a time, so a request that comes before the previous
  accepted one was said to be set means that one was refused after the node accepted it: its
  change is dropped (and reverted like a failed one), as is a change whose parameters are not
  set within ``SET_WITHIN_S``.
"""
from __future__ import annotations

import dataclasses
import threading
import time
from typing import Any, Callable

#: how long a parameter request waits for its change to be prepared before it is answered as
#: accepted and pending, s
ANSWER_WITHIN_S = 0.5
#: how long /diagnostics reports a reverted change, s
REVERT_REPORT_S = 10.0
#: how long a prepared change waits for its parameters to be set before it is dropped, s
SET_WITHIN_S = 10.0


class ChangeRefused(Exception):
    """A change that cannot be made; its message says why (nothing has changed)."""


@dataclasses.dataclass
class _Change:
    incoming: dict[str, Any]
    done: threading.Event = dataclasses.field(default_factory=threading.Event)
    refusal: str = ''
    finished: bool = False     # prepared (or refused): its outcome is decided
    answered: bool = False     # answered as pending before it was prepared
    unset: int = 0             # accepted requests whose parameters are not set yet
    dropped: str = ''          # why it must not be committed (a request of it was not set)


@dataclasses.dataclass(frozen=True)
class PreparerState:
    """What the preparer is doing, for ``/diagnostics``."""

    preparing: str = ''        # the parameters being prepared (name=value, ...), or empty
    reverted: str = ''         # the last change reverted recently, and why, or empty
    since: float = 0.0         # when the change being prepared began (monotonic), or 0


def describe(values: dict[str, Any]) -> str:
    return ', '.join(f'{name}={value!r}' for name, value in sorted(values.items()))


class ChangePreparer:
    """
    Prepares slow parameter changes one at a time in its own thread.

    ``prepare(incoming)`` does the slow part and raises :class:`ChangeRefused` (or returns) with
    nothing changed; ``commit(incoming, prepared)`` hands the prepared change to the run, once
    :meth:`parameters_set` said its parameters are set; ``revert(incoming, reason)`` undoes the
    parameters of a change answered as accepted that then failed. The three are called from the
    preparer's thread.
    """

    def __init__(self, prepare: Callable[[dict[str, Any]], Any],
                 commit: Callable[[dict[str, Any], Any], None],
                 revert: Callable[[dict[str, Any], str], None],
                 answer_within_s: float = ANSWER_WITHIN_S, name: str = 'parameter_changes'):
        self._prepare = prepare
        self._commit = commit
        self._revert = revert
        self.answer_within_s = float(answer_within_s)
        self._cond = threading.Condition()
        self._current: _Change | None = None     # being prepared
        self._since = 0.0                          # since when (monotonic)
        self._pending: _Change | None = None     # next, collecting newer requests
        self._stopped = False
        self._reverted = ('', -float('inf'))     # (what and why, monotonic time)
        self._awaiting: _Change | None = None    # the last accepted request's, until it is set
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    # -- from the parameter callback -----------------------------------------------------------
    def request(self, incoming: dict[str, Any]) -> tuple[bool, str]:
        """
        Hand a validated change over; return (accepted, reason) to answer the request with.

        Accepted with an empty reason: prepared in time (committed once
        :meth:`parameters_set` is called); with a reason starting ``pending``: accepted, still
        being prepared (or queued behind another change). Requests come one at a time: an
        accepted one is followed by :meth:`parameters_set` once its parameters are set, before
        the next request (one that comes first drops it).
        """
        with self._cond:
            if self._stopped:
                return False, 'the node is shutting down'
            self._never_set()
            if self._current is not None or self._pending is not None:
                if self._pending is None:
                    self._pending = _Change(dict(incoming))
                else:
                    self._pending.incoming.update(incoming)    # newer values supersede
                self._pending.answered = True
                self._accept(self._pending)
                return True, f'pending: queued behind {describe(self._busy_with())}'
            change = _Change(dict(incoming))
            self._pending = change
            self._accept(change)
        change.done.wait(self.answer_within_s)
        with self._cond:
            if change.finished and change.refusal:
                change.unset -= 1
                self._awaiting = None
                return False, change.refusal
            if not change.finished:
                change.answered = True
                return True, f'pending: preparing {describe(change.incoming)}'
        return True, ''

    def _accept(self, change: _Change) -> None:
        change.unset += 1
        self._awaiting = change
        self._cond.notify_all()

    def _never_set(self) -> None:
        """Drop the change of an accepted request refused after it (a new request came first)."""
        change, self._awaiting = self._awaiting, None
        if change is not None:
            change.unset -= 1
            change.dropped = 'refused after the node accepted it (its parameters were not set)'
            self._cond.notify_all()

    def parameters_set(self) -> None:
        """Say that the parameters of the last accepted request are set."""
        with self._cond:
            change, self._awaiting = self._awaiting, None
            if change is not None:
                change.unset -= 1
                self._cond.notify_all()

    @property
    def busy(self) -> bool:
        with self._cond:
            return self._current is not None or self._pending is not None

    def state(self) -> PreparerState:
        with self._cond:
            busy = self._busy_with()
            what, when = self._reverted
            since = self._since if self._current is not None else 0.0
        recent = time.monotonic() - when < REVERT_REPORT_S
        return PreparerState(describe(busy) if busy else '', what if recent else '', since)

    def wait_idle(self, timeout: float) -> bool:
        """Wait until nothing is being prepared or pending; True when idle."""
        end = time.monotonic() + timeout
        with self._cond:
            while self._current is not None or self._pending is not None:
                left = end - time.monotonic()
                if left <= 0:
                    return False
                self._cond.wait(left)
        return True

    def stopping(self) -> None:
        """
        Take no more changes, and let the one being prepared end without effect.

        Nothing committed, nothing reverted: said before what it waits on is closed (the
        worker process), so that its failure then is not taken for the change's.
        """
        with self._cond:
            self._stopped = True
            self._cond.notify_all()

    def stop(self, timeout: float = 5.0) -> None:
        """Stop taking changes; a change being prepared is abandoned (nothing committed)."""
        self.stopping()
        if self._thread is not threading.current_thread():
            self._thread.join(timeout)

    # -- the thread ----------------------------------------------------------------------------
    def _busy_with(self) -> dict[str, Any]:
        merged: dict[str, Any] = {}
        for change in (self._current, self._pending):
            if change is not None:
                merged.update(change.incoming)
        return merged

    def _run(self) -> None:
        while True:
            with self._cond:
                while self._pending is None and not self._stopped:
                    self._cond.wait()
                if self._stopped:
                    return
                change, self._pending = self._pending, None
                self._current, self._since = change, time.monotonic()
            try:
                self._prepare_one(change)
            except Exception as exc:  # reverting failed: said on /diagnostics, the thread goes on
                with self._cond:
                    self._reverted = (f'{describe(change.incoming)}: could not revert: {exc!r}',
                                      time.monotonic())
            finally:
                with self._cond:
                    self._current = None
                    self._cond.notify_all()

    def _prepare_one(self, change: _Change) -> None:
        refusal, prepared = '', None
        try:
            prepared = self._prepare(change.incoming)
        except ChangeRefused as exc:
            refusal = str(exc)
        except Exception as exc:  # a failure is a refusal: the run stays as it is
            refusal = f'could not prepare the change: {exc!r}'
        with self._cond:
            stopped = self._stopped
            change.refusal = refusal or ('the node is shutting down' if stopped else '')
            change.finished = True
            revert = bool(refusal) and change.answered and not stopped
            if revert:
                self._reverted = (f'{describe(change.incoming)} reverted: {refusal}',
                                  time.monotonic())
        change.done.set()           # the outcome is told; a refused one sets nothing
        if revert:
            self._revert(change.incoming, refusal)
        elif not change.refusal:
            dropped = self._wait_set(change)
            if dropped:
                self._revert(change.incoming, dropped)
            elif dropped is not None:
                self._commit(change.incoming, prepared)

    def _wait_set(self, change: _Change) -> str | None:
        """
        Wait until every request of ``change`` has its parameters set.

        Return '' (commit it), why it is dropped, or None (the preparer stopped).
        """
        end = time.monotonic() + SET_WITHIN_S
        with self._cond:
            while change.unset > 0 and not self._stopped and time.monotonic() < end:
                self._cond.wait(end - time.monotonic())
            if self._stopped:
                return None
            if change.unset > 0:
                change.dropped = f'its parameters were not set within {SET_WITHIN_S:g} s'
            if change.dropped:
                self._reverted = (f'{describe(change.incoming)} dropped: {change.dropped}',
                                  time.monotonic())
            return change.dropped

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
  on ``/diagnostics``.
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


class ChangeRefused(Exception):
    """A change that cannot be made; its message says why (nothing has changed)."""


@dataclasses.dataclass
class _Change:
    incoming: dict[str, Any]
    done: threading.Event = dataclasses.field(default_factory=threading.Event)
    refusal: str = ''
    finished: bool = False     # prepared (or refused): its outcome is decided
    answered: bool = False     # answered as pending before it was prepared


@dataclasses.dataclass(frozen=True)
class PreparerState:
    """What the preparer is doing, for ``/diagnostics``."""

    preparing: str = ''        # the parameters being prepared (name=value, ...), or empty
    reverted: str = ''         # the last change reverted recently, and why, or empty


def describe(values: dict[str, Any]) -> str:
    return ', '.join(f'{name}={value!r}' for name, value in sorted(values.items()))


class ChangePreparer:
    """
    Prepares slow parameter changes one at a time in its own thread.

    ``prepare(incoming)`` does the slow part and raises :class:`ChangeRefused` (or returns) with
    nothing changed; ``commit(incoming, prepared)`` hands the prepared change to the run;
    ``revert(incoming, reason)`` undoes the parameters of a change answered as accepted that then
    failed. The three are called from the preparer's thread.
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
        self._pending: _Change | None = None     # next, collecting newer requests
        self._stopped = False
        self._reverted = ('', -float('inf'))     # (what and why, monotonic time)
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    # -- from the parameter callback -----------------------------------------------------------
    def request(self, incoming: dict[str, Any]) -> tuple[bool, str]:
        """
        Hand a validated change over; return (accepted, reason) to answer the request with.

        Accepted with an empty reason: applied (prepared in time); with a reason starting
        ``pending``: accepted, still being prepared (or queued behind another change).
        """
        with self._cond:
            if self._stopped:
                return False, 'the node is shutting down'
            if self._current is not None or self._pending is not None:
                if self._pending is None:
                    self._pending = _Change(dict(incoming))
                else:
                    self._pending.incoming.update(incoming)    # newer values supersede
                self._pending.answered = True
                self._cond.notify_all()
                return True, f'pending: queued behind {describe(self._busy_with())}'
            change = _Change(dict(incoming))
            self._pending = change
            self._cond.notify_all()
        change.done.wait(self.answer_within_s)
        with self._cond:
            if not change.finished:
                change.answered = True
                return True, f'pending: preparing {describe(change.incoming)}'
        return (False, change.refusal) if change.refusal else (True, '')

    @property
    def busy(self) -> bool:
        with self._cond:
            return self._current is not None or self._pending is not None

    def state(self) -> PreparerState:
        with self._cond:
            busy = self._busy_with()
            what, when = self._reverted
        recent = time.monotonic() - when < REVERT_REPORT_S
        return PreparerState(describe(busy) if busy else '', what if recent else '')

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

    def stop(self, timeout: float = 5.0) -> None:
        """Stop taking changes; a change being prepared is abandoned (nothing committed)."""
        with self._cond:
            self._stopped = True
            self._cond.notify_all()
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
                self._current = change
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
        refusal = ''
        try:
            prepared = self._prepare(change.incoming)
            with self._cond:
                stopped = self._stopped
            if not stopped:     # committed before the outcome is told: an answer is the truth
                self._commit(change.incoming, prepared)
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
        try:
            if revert:
                self._revert(change.incoming, refusal)
        finally:
            change.done.set()

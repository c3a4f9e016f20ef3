"""
Typed state changes handed from the executor's threads to the simulation thread.

Every change of the running simulation (a band, a new simulation for other settings, a reset,
a pause) is one request. The executor's callbacks do the slow, failing part (validation,
computing modes, building operators) before they submit it; the simulation thread applies
requests one at a time between two steps, in the order they came, so no request sees or leaves
a half-built state. Each request is answered: :meth:`Request.wait` returns whether it was
applied (blocking a thread), :func:`applied_within` awaits the same in an executor's coroutine
(holding no thread), and :attr:`Request.message` says what happened.
"""
from __future__ import annotations

import dataclasses
import queue
import threading
import time
from typing import Any, Callable

from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.simulations import Simulation


@dataclasses.dataclass(eq=False)
class Request:
    """A state change, answered once the simulation thread has applied (or refused) it."""

    applied: bool = dataclasses.field(default=False, init=False)
    message: str = dataclasses.field(default='', init=False)
    _done: threading.Event = dataclasses.field(default_factory=threading.Event, init=False,
                                               repr=False)
    #: called (from the simulation thread) once the request is answered, e.g. to wake an executor
    on_finish: Callable[[], None] | None = dataclasses.field(default=None, init=False,
                                                             repr=False)

    def finish(self, applied: bool, message: str) -> None:
        self.applied, self.message = applied, message
        self._done.set()
        if self.on_finish is not None:
            self.on_finish()

    def wait(self, timeout: float) -> bool:
        """Return True when the request was applied within ``timeout`` seconds."""
        return self._done.wait(timeout) and self.applied

    @property
    def answered(self) -> bool:
        return self._done.is_set()


class _NextWake:
    """Awaitable that hands the thread back to the executor once: resumed at its next wake-up."""

    def __await__(self):
        yield


async def applied_within(request: Request, timeout: float) -> bool:
    """
    Await ``request``'s answer for up to ``timeout`` seconds in an rclpy executor's coroutine.

    Unlike :meth:`Request.wait` it holds no executor thread while the simulation thread works,
    so requests waiting together never queue behind one another. The executor resumes the
    coroutine whenever it wakes: whoever answers must wake it (``Request.on_finish``), and
    something periodic must wake it for the timeout to be seen.
    """
    deadline = time.monotonic() + timeout
    while not request.answered and time.monotonic() < deadline:
        await _NextWake()
    return request.answered and request.applied


@dataclasses.dataclass(eq=False)
class ChangeBand(Request):
    """Switch the running simulation to ``band`` (its operators prepared ahead)."""

    band: FilterBand = FilterBand()
    transition_s: float | None = None
    changed: dict[str, Any] = dataclasses.field(default_factory=dict)


@dataclasses.dataclass(eq=False)
class ReplaceSimulation(Request):
    """Continue with ``simulation`` (other settings), from the running one's state and time."""

    simulation: Simulation | None = None
    changed: dict[str, Any] = dataclasses.field(default_factory=dict)


@dataclasses.dataclass(eq=False)
class Reset(Request):
    """Back to the rest state at t = 0, the band settled."""


@dataclasses.dataclass(eq=False)
class Pause(Request):
    """Stop (or restart) stepping and publishing."""

    paused: bool = True


@dataclasses.dataclass(eq=False)
class Step(Request):
    """While paused: advance ``frames`` frames' worth of simulated time, publishing each."""

    frames: int = 1


class StepRefused(RuntimeError):
    """A step that cannot be made (the run is not paused), or that diverged (reported apart)."""


@dataclasses.dataclass(eq=False)
class TakeInput(Request):
    """An accepted input message (:mod:`~modal_spring_ros.ros.inputs.input_kinds`) to apply."""

    kind: Any = None               # its InputKind
    received: Any = None           # the message, already checked
    values: dict[str, Any] = dataclasses.field(default_factory=dict)   # parameters it came with


def _replaces(request: Request, following: Request | None) -> bool:
    """
    Tell whether ``following`` replaces ``request`` outright.

    The run keeps one band, and one of each input's effects (the clamp follows the last pose,
    one point pulls): a band change a band change follows, an input one of its kind follows
    (of its kind and key: the pose of one frame does not replace another frame's).
    """
    if type(following) is not type(request):
        return False
    return isinstance(request, ChangeBand) or (
        isinstance(request, TakeInput) and request.kind is following.kind
        and request.kind.key(request.received) == following.kind.key(following.received))


def drained(requests: 'queue.Queue[Request]') -> list[Request]:
    """Return every request queued now, in the order they came (without waiting)."""
    batch = []
    while True:
        try:
            batch.append(requests.get_nowait())
        except queue.Empty:
            return batch


def without_superseded(batch: list[Request]) -> list[Request]:
    """
    Answer each request of ``batch`` that the next one replaces; return the others, in order.

    A replaced request would never be stepped. It is answered as applied and superseded; a band
    change's parameters pass to the later one (so a capture records them), and a skipped input
    is not recorded, as it never acted.
    """
    kept = []
    for request, following in zip(batch, batch[1:] + [None]):
        if not _replaces(request, following):
            kept.append(request)
        elif isinstance(request, ChangeBand):
            following.changed = {**request.changed, **following.changed}
            request.finish(True, f'band {request.band.describe()}, superseded by '
                                 f'{following.band.describe()}')
        else:
            request.finish(True, f'superseded by a newer {request.kind.name} before the next '
                                 'step')
    return kept

"""
How the simulation thread applies each kind of request.

One handler a request type (:mod:`~modal_spring_ros.ros.changes.requests`), each over the
:class:`RunHost` the thread is to it: the running simulation and what the thread keeps beside it
(its outputs, its book, the plan's watch, the divergence streak). A handler returns what
happened, or raises with the run unchanged: ``StepRefused`` and ``HeldError`` are answers, any
other exception a refusal the thread reports. A new kind of request is a dataclass in
``requests`` and one handler in :data:`HANDLERS`.
"""
from __future__ import annotations

from typing import Callable, Protocol

from modal_spring_ros.core.simulations import Simulation
from modal_spring_ros.ros.changes.requests import (ChangeBand, Pause, ReplaceSimulation, Request,
                                                   Reset, Step, StepRefused, TakeInput)
from modal_spring_ros.ros.inputs.input_kinds import recorded_messages
from modal_spring_ros.ros.stream.divergence_streak import DivergenceStreak
from modal_spring_ros.ros.stream.outputs import Outputs
from modal_spring_ros.ros.stream.plan_watch import PlanWatch
from modal_spring_ros.ros.stream.stream_book import StreamBook
from modal_spring_ros.ros.stream.stream_settings import StreamSettings


class RunHost(Protocol):
    """What the handlers read and change on the thread that applies them (it alone runs them)."""

    sim: Simulation
    paused: bool
    outputs: Outputs
    book: StreamBook
    plan_watch: PlanWatch
    streak: DivergenceStreak

    def settings(self) -> StreamSettings:
        """Return the stream's settings of the moment."""

    def reanchor(self, window_valid: bool) -> None:
        """Keep pace from the run's time now (the measuring window kept or dropped)."""

    def step_until(self, target: float, deadline: float) -> None:
        """Step to ``target`` simulated seconds, or until the wall clock passes ``deadline``."""

    def publish_frame(self, mesh: bool) -> None:
        """Publish the run's state as a frame (and the mesh)."""


def apply_request(host: RunHost, request: Request) -> str:
    """Apply one request; return what happened. Raises with the run unchanged."""
    return HANDLERS[type(request)](host, request)


def _take_input(host: RunHost, request: TakeInput) -> str:
    host.streak.refuse_while_held()
    message = request.kind.apply(host.sim, request.received, request.values)
    host.plan_watch.took_input(host.sim)
    host.outputs.received(host.sim, recorded_messages(request.kind, request.received))
    return message


def _change_band(host: RunHost, request: ChangeBand) -> str:
    host.sim.set_band(request.band, request.transition_s)
    host.plan_watch.band_changed(host.sim)
    host.outputs.changed(host.sim, request.changed)
    return f'band {request.band.describe()}'


def _replace(host: RunHost, request: ReplaceSimulation) -> str:
    request.simulation.take_over(host.sim)
    host.sim = request.simulation
    host.outputs.changed(host.sim, request.changed)
    host.reanchor(window_valid=False)
    return f'{host.sim.method} run continues'


def _reset(host: RunHost, request: Reset) -> str:
    host.sim.model.motion.clear()  # a followed clamp forgets its poses
    host.sim.reset()
    host.streak.clear()
    host.plan_watch.restart()
    host.reanchor(window_valid=False)
    return 'back to the rest state at t = 0'


def _pause(host: RunHost, request: Pause) -> str:
    host.paused = request.paused
    host.reanchor(window_valid=False)
    return 'paused' if request.paused else 'running'


def _step(host: RunHost, request: Step) -> str:
    """Advance ``request.frames`` frame periods (times the real-time factor), publish each."""
    if not host.paused:
        raise StepRefused('stepping is for a paused run: call ~/pause with true first')
    host.streak.refuse_while_held()
    book = host.book
    settings, steps, divergences = host.settings(), book.window.steps, book.divergences
    period = (settings.realtime_factor or 1.0) / settings.publish_rate_hz
    for _ in range(request.frames):
        host.step_until(host.sim.time + period, float('inf'))
        if book.divergences != divergences:
            raise StepRefused(f'{book.last_divergence} (reported on /diagnostics)')
        book.frame_after_pause()
        host.publish_frame(settings.mesh_rate_hz > 0)
    return (f'stepped {book.window.steps - steps} steps '
            f'({request.frames} frame{"s" if request.frames != 1 else ""}) to '
            f't = {host.sim.time:.6g} s')


#: request type -> its handler
HANDLERS: dict[type, Callable[[RunHost, Request], str]] = {
    ChangeBand: _change_band, ReplaceSimulation: _replace, Reset: _reset, Pause: _pause,
    Step: _step, TakeInput: _take_input}

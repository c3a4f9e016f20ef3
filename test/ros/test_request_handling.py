"""
The request handlers over a stand-in for the simulation thread (their :class:`RunHost`).

No thread and no DDS: a host holding a real simulation, a book and a recorder of what it is
asked, so that each handler is checked on what it changes, publishes and answers.
"""
from __future__ import annotations

from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.ros.changes.requests import Pause, Reset, Step, StepRefused
from modal_spring_ros.ros.stream.divergence_streak import DivergenceStreak
from modal_spring_ros.ros.stream.plan_watch import PlanWatch
from modal_spring_ros.ros.stream.request_handling import apply_request, HANDLERS
from modal_spring_ros.ros.stream.stream_book import StreamBook
from modal_spring_ros.ros.stream.stream_settings import StreamSettings
from modal_spring_ros.scenes.resources import load_scene
import pytest

RATE = 50.0


class Host:
    """A :class:`RunHost` without a thread: it steps when asked and keeps what it publishes."""

    def __init__(self):
        self.sim = build_simulation(load_scene('chain_2'), SimulationConfig())
        self.paused = False
        self.outputs = None
        self.book = StreamBook(self.sim.status(), lambda: False)
        self.plan_watch = PlanWatch(lambda window, plan: None)
        self.streak = DivergenceStreak()
        self.published: list[float] = []
        self.anchored = 0

    def settings(self) -> StreamSettings:
        return StreamSettings(RATE, 0.0, 1.0, 0.5, 0.0)

    def reanchor(self, window_valid: bool) -> None:
        self.anchored += 1

    def step_until(self, target: float, deadline: float) -> None:
        while self.sim.time + 0.5 * self.sim.dt < target:
            self.sim.step()
            self.book.stepped(0.0)

    def publish_frame(self, mesh: bool) -> None:
        self.published.append(self.sim.time)


def test_every_request_type_has_a_handler():
    from modal_spring_ros.ros.changes import requests
    kinds = {cls for cls in vars(requests).values() if isinstance(cls, type)
             and issubclass(cls, requests.Request) and cls is not requests.Request}
    assert kinds == set(HANDLERS)


def test_steps_publish_a_frame_each_only_while_paused_and_a_reset_goes_back_to_t_0():
    host = Host()
    with pytest.raises(StepRefused, match='paused'):
        apply_request(host, Step(frames=2))
    assert not host.published and host.sim.time == 0.0                # refused: nothing moved
    assert apply_request(host, Pause(paused=True)) == 'paused' and host.paused
    message = apply_request(host, Step(frames=3))
    assert message.startswith('stepped') and '(3 frames)' in message
    assert host.published == pytest.approx([1 / RATE, 2 / RATE, 3 / RATE], abs=host.sim.dt)
    assert apply_request(host, Reset()) == 'back to the rest state at t = 0'
    assert host.sim.time == 0.0 and host.paused                       # a reset keeps the pause
    assert host.anchored == 2                                          # pause, reset

"""The simulation time a run owes by the clock it keeps pace with (``ros/stream/run_pace.py``)."""
from __future__ import annotations

from modal_spring_ros.ros.stream.run_pace import pace_reading, RunPace
import pytest


class FakeClock:
    """A pace clock the test sets: its name and time."""

    def __init__(self, source: str = 'ros', now: float = 0.0):
        self.source, self.now = source, now

    def __call__(self):
        return self.source, self.now


def test_a_run_owes_the_clock_s_advance_times_the_rate():
    clock = FakeClock('wall', 10.0)
    pace = RunPace(clock, sim_time=2.0)
    clock.now = 10.5
    assert pace.owed(2.0, rtf=1.0) == (2.5, False)
    assert pace.owed(2.0, rtf=0.5) == (2.25, False)
    # the debt beyond a frame is dropped: owing starts again from the last reading
    pace.anchor(2.1, at_last_reading=True)
    clock.now = 10.6
    assert pace.owed(2.1, rtf=1.0) == (pytest.approx(2.2), False)


def test_a_clock_that_stands_still_owes_nothing_and_says_so():
    clock = FakeClock('ros', 500.0)
    pace = RunPace(clock, sim_time=1.0)
    start = pace.read()
    assert pace.owed(1.0, rtf=1.0) == (1.0, False)
    assert pace.since(start) == (0.0, True)                  # a /clock that did not advance
    clock.now = 500.25
    assert pace.since(start) == (0.25, False)
    wall = RunPace(FakeClock('wall', 3.0))
    assert wall.since(wall.read()) == (0.0, False)           # the wall never "stands still"


@pytest.mark.parametrize('jump', ['back', 'first /clock', 'other clock'])
def test_a_jump_of_the_clock_is_followed_from_where_the_run_is(jump):
    clock = FakeClock('ros', 0.0 if jump == 'first /clock' else 800.0)
    pace = RunPace(clock, sim_time=4.0)
    if jump == 'back':
        clock.now = 100.0                                    # a bag played in a loop
    elif jump == 'first /clock':
        clock.now = 1.7e9                                    # ROS time 0 until the first one
    else:
        clock.source, clock.now = 'wall', 12.0               # use_sim_time set false
    assert pace.owed(4.5, rtf=1.0) == (4.5, True)            # neither owing nor ahead
    clock.now += 0.1
    assert pace.owed(4.5, rtf=1.0) == (pytest.approx(4.6), False)


class FakeRosClock:
    """What ``pace_reading`` reads of rclpy's ``Clock``."""

    def __init__(self, active: bool, nanoseconds: int):
        self.ros_time_is_active = active
        self._ns = nanoseconds

    def now(self):
        return type('Time', (), {'nanoseconds': self._ns})()


def test_the_node_keeps_pace_with_another_clock_only_when_it_follows_one():
    assert pace_reading(FakeRosClock(True, 1_500_000_000), publish_clock=False) == ('ros', 1.5)
    # its own clock would wait on its own steps; without use_sim_time it is the wall's
    assert pace_reading(FakeRosClock(True, 1_500_000_000), publish_clock=True)[0] == 'wall'
    assert pace_reading(FakeRosClock(False, 1_500_000_000), publish_clock=False)[0] == 'wall'

"""Published time never goes back: a reset moves the offset on (StreamTime, and the live node)."""
from __future__ import annotations

import threading
import time

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from modal_spring_ros.ros.parameters import CLOCK_OFFSET
from modal_spring_ros.ros.stream.stream_time import (clock_warnings, stamps_in_simulation_time,
                                                     StreamTime)
import numpy as np
import pytest
from ros_harness import frames_since, node_of, node_with_client, SimTimes, wait_for
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import PointCloud2
from std_srvs.srv import Trigger


def _seconds(stamp) -> float:
    return stamp.sec + 1e-9 * stamp.nanosec


def test_published_time_goes_on_from_the_time_reached_when_simulation_time_goes_back():
    moves = []
    clock = StreamTime(moved=moves.append)
    assert [clock.at(t) for t in (0.0, 0.1, 0.5)] == [0.0, 0.1, 0.5]
    assert moves == [] and clock.offset == 0.0
    assert clock.at(0.02, 0.01) == pytest.approx(0.53)    # reset at 0.5: on from 0.5 + a step
    assert moves == [pytest.approx(0.51)] and clock.offset == pytest.approx(0.51)
    assert clock.at(0.3, 0.01) == pytest.approx(0.81)
    assert clock.reached == pytest.approx(0.81)
    assert clock.at(0.3, 0.01) == pytest.approx(0.81)     # a paused frame: the same time
    assert clock.at(0.0, 0.01) == pytest.approx(0.82)     # the rest state at 0: a step later
    assert moves == [pytest.approx(0.51), pytest.approx(0.82)]
    again = StreamTime(clock.reached)                     # a node configured again
    assert again.at(0.01) == pytest.approx(0.83)


def test_stamps_of_its_own_time_under_another_clock_are_warned_about():
    own = {'stamp': 'sim', 'publish_clock': False}
    (warning,) = clock_warnings(True, own)
    assert 'use_sim_time' in warning and 'stamp:=wall' in warning
    assert clock_warnings(False, own) == []                       # its own time, no other
    assert clock_warnings(True, dict(own, stamp='wall')) == []     # the other clock's time
    assert clock_warnings(True, dict(own, publish_clock=True)) == []   # it is the clock
    assert clock_warnings(True, dict(own, stamp='auto')) == []     # the default: the other's


def test_auto_stamps_with_simulation_time_only_where_the_node_is_the_clock():
    assert stamps_in_simulation_time({'stamp': 'auto', 'publish_clock': True})
    assert not stamps_in_simulation_time({'stamp': 'auto', 'publish_clock': False})
    assert stamps_in_simulation_time({'stamp': 'sim', 'publish_clock': False})
    assert not stamps_in_simulation_time({'stamp': 'wall', 'publish_clock': True})


@pytest.mark.ros
def test_a_reset_sends_neither_clock_nor_stamps_back_and_reports_the_offset():
    with node_with_client('publish_clock:=true', 'publish_rate_hz:=30.0',
                          namespace='monotonic') as (node, client):
        points = client.collect(PointCloud2, '/monotonic/points', qos=500)
        clocks = client.collect(Clock, '/clock', qos=500)
        assert wait_for(lambda: len(points) > 20, 30)
        assert client.get_parameters('monotonic/modal_spring', CLOCK_OFFSET) == [0.0]
        before = _seconds(points[-1][1].header.stamp)
        assert client.call(Trigger, '/monotonic/modal_spring/reset', Trigger.Request()).success
        frames_since(points, time.monotonic(), 20, timeout=60)
        (offset,) = client.get_parameters('monotonic/modal_spring', CLOCK_OFFSET)
        stamps = np.array([_seconds(m.header.stamp) for _, m in points])
        ticks = np.array([_seconds(c.clock) for _, c in clocks])
        assert np.all(np.diff(stamps) > 0), 'a stamp went back'
        assert np.all(np.diff(ticks) >= 0), '/clock went back'
        # the offset is the time reached at the reset (and a step): the run starts again there
        assert before < offset <= stamps[-1] + 1e-9                # stamps: whole ns
        first = stamps[stamps > offset - 1e-9][0]
        assert first - offset < 0.2                            # t is small again
        (refused,) = client.set_parameters('monotonic/modal_spring', clock__offset_s=0.0)
        assert not refused.successful and 'read-only' in refused.reason


@pytest.mark.ros
def test_under_another_clock_the_default_stamps_are_that_clock_s_time():
    """``use_sim_time:=true`` (stamp ``auto``): a bag's or a simulator's /clock stamps it."""
    with node_with_client('use_sim_time:=true', namespace='other_clock') as (node, client):
        publisher = client.node.create_publisher(Clock, '/clock', 10)
        sim_time = SimTimes().subscribe(client, '/other_clock/sim_time')
        points = client.collect(PointCloud2, '/other_clock/points', qos=500)
        ticks, stop = [], threading.Event()

        def tick():
            t = 1000.0                                    # far from the wall clock and from 0
            while not stop.is_set():
                publisher.publish(Clock(clock=Time(sec=int(t), nanosec=int(t % 1 * 1e9))))
                ticks.append(t)
                t += 0.01
                time.sleep(0.01)
        ticker = threading.Thread(target=tick, daemon=True)
        ticker.start()
        try:
            # once the node has the other clock, every frame is stamped with its time
            assert wait_for(lambda: any(_seconds(m.header.stamp) >= 1000.0
                                        for _, m in list(points)), 30)
            window = frames_since(points, time.monotonic(), 10)
        finally:
            stop.set()
            ticker.join(5)
        stamps = [_seconds(m.header.stamp) for m in window]
        assert all(1000.0 <= s <= ticks[-1] + 1e-6 for s in stamps), stamps
        # and beside each frame, its own simulation time (the node runs from 0)
        times = np.array([sim_time(m) for m in window])
        assert np.all(np.diff(times) >= 0) and times[0] < times[-1] < 100.0, times


@pytest.mark.slow
def test_under_another_clock_the_run_keeps_pace_with_it_and_waits_when_it_stops():
    """
    ``use_sim_time:=true``: the run follows /clock (here at half the wall's rate), not the wall.

    A simulator under another clock advances as that clock does: a bag played at half speed
    slows it, a paused one pauses it (no new frames, /diagnostics says it waits).
    """
    with node_with_client('use_sim_time:=true', namespace='paced') as (node, client):
        publisher = client.node.create_publisher(Clock, '/clock', 10)
        sim_time = SimTimes().subscribe(client, '/paced/sim_time')
        points = client.collect(PointCloud2, '/paced/points', qos=500)
        diags = client.collect(DiagnosticArray, '/diagnostics')
        clock, running, stop = [500.0], threading.Event(), threading.Event()

        def tick():
            while not stop.is_set():
                if running.is_set():
                    clock[0] += 0.005                     # 5 ms of clock each 10 ms of wall
                t = clock[0]
                publisher.publish(Clock(clock=Time(sec=int(t), nanosec=int(t % 1 * 1e9))))
                time.sleep(0.01)
        ticker = threading.Thread(target=tick, daemon=True)
        running.set()
        ticker.start()
        try:
            assert wait_for(lambda: any(_seconds(m.header.stamp) >= 500.0
                                        for _, m in list(points)), 30)
            # past the start, where a run still settling may drop what it cannot catch up
            window = frames_since(points, time.monotonic() + 1.5, 90, timeout=60)
            running.clear()                                # the clock stands still
            time.sleep(0.5)                                # frames already made arrive
            held = len(points)
            last = sim_time(points[-1][1])
            time.sleep(2.5)
            later = [sim_time(m) for _, m in list(points)[held:]]
            waiting = [s for _, d in list(diags) for s in d.status
                       if node_of(s).startswith('/paced/')]
        finally:
            stop.set()
            ticker.join(5)
        # the simulation advanced as the clock did (stamps are the clock's time), not as the wall
        # (twice the clock here): never ahead of it, and behind only by what a run that cannot
        # keep up on a busy machine drops (a frame's debt at a time, as under the wall's pace)
        first, final = window[0], window[-1]
        clock_span = _seconds(final.header.stamp) - _seconds(first.header.stamp)
        sim_span = sim_time(final) - sim_time(first)
        assert clock_span > 0.4, clock_span
        assert 0.3 < sim_span / clock_span < 1.1, (sim_span, clock_span)
        # with the clock stopped the run waits: no new simulation time, and it says why
        assert all(t <= last + 1e-9 for t in later), (last, later)
        assert any('waiting for /clock' in s.message for s in waiting), [
            s.message for s in waiting]

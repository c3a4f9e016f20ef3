"""
The node's simulation thread on its own (no DDS).

Requests applied between steps and always answered, supervision that reports a failure and keeps
the stream going, and "as fast as possible" filling each frame with steps.
"""
from __future__ import annotations

import threading
import time

from helpers import variant
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation, rebuild
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.ros.changes.requests import (ChangeBand, Pause, ReplaceSimulation, Reset,
                                                   TakeInput)
from modal_spring_ros.ros.inputs.input_kinds import CLICKED_POINT
from modal_spring_ros.ros.stream import simulation_thread
from modal_spring_ros.ros.stream.simulation_thread import SimulationThread
from modal_spring_ros.ros.stream.stream_settings import StreamSettings
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest

pytestmark = pytest.mark.ros  # the node's own thread (no DDS, but seconds of wall time)


class Recorder:
    """Outputs that keep what the thread publishes."""

    def __init__(self):
        self.frames: list[tuple[float, float, np.ndarray]] = []  # wall, sim time, positions
        self.reports = []
        self.logs = []
        self.changes: list[dict] = []
        self.inputs: list = []

    def frame(self, sim, cloud, mesh):
        self.frames.append((time.monotonic(), sim.time, cloud.points[:, :3].astype(float)))

    def diagnostics(self, status, report):
        self.reports.append((status, report))

    def changed(self, sim, changed):
        self.changes.append(dict(changed))

    def received(self, sim, recorded):
        self.inputs.extend(recorded)

    def log(self, level, message):
        self.logs.append((level, message))

    def errors(self):
        return [r.error for _, r in self.reports if r.error]

    def frames_after(self, wall):
        return [f for f in self.frames if f[0] >= wall]


def wait_for(predicate, timeout):
    end = time.monotonic() + timeout
    while time.monotonic() < end and not predicate():
        time.sleep(0.01)
    return predicate()


@pytest.fixture
def running():
    """Return a running thread on sheet_10x10 (modal, all-pass) and its recorder; stopped after."""
    started = []

    def start(sim=None, settings=StreamSettings()):
        sim = sim or build_simulation(load_scene('sheet_10x10'), SimulationConfig())
        out = Recorder()
        thread = SimulationThread(sim, out, lambda: settings,
                                  rebuild=lambda: rebuild(sim.model, sim.basis,
                                                          SimulationConfig()))
        thread.start()
        started.append(thread)
        assert wait_for(lambda: len(out.frames) > 3, 5.0)
        return thread, out

    yield start
    for thread in started:
        thread.stop()
        assert not thread.alive


def test_a_reset_while_a_band_fades_is_applied_and_the_stream_goes_on(running):
    thread, out = running()
    band = ChangeBand(band=FilterBand('lowpass', 0, 20, 'hz'), transition_s=0.5)
    reset = Reset()
    thread.submit(band)
    thread.submit(reset)
    assert band.wait(2.0) and reset.wait(2.0), (band.message, reset.message)
    assert reset.message == 'back to the rest state at t = 0'
    after = time.monotonic()
    assert wait_for(lambda: len(out.frames_after(after)) > 10, 5.0)
    assert out.errors() == []
    assert thread.sim.kept_modes.tolist() == [0, 1, 2, 3] and not thread.sim.fading


def test_a_failing_step_is_reported_and_the_run_goes_back_to_rest(running, monkeypatch):
    thread, out = running()
    sim = thread.sim
    real = sim._step_once
    calls = []

    def failing_once():
        calls.append(1)
        if len(calls) == 50:
            raise RuntimeError('boom')
        real()

    monkeypatch.setattr(sim, '_step_once', failing_once)
    assert wait_for(lambda: out.errors(), 5.0)
    assert out.errors()[0] == ("simulation thread failed: RuntimeError('boom'); recovered: "
                               'back to the rest state')
    after = time.monotonic()
    assert wait_for(lambda: len(out.frames_after(after)) > 10, 5.0)
    assert thread.sim is sim and thread.alive
    # the run started again from rest: its time went back to (about) zero after the failure
    times = [t for _, t, _ in out.frames]
    assert min(np.diff(times)) < 0
    assert all(np.isfinite(p).all() for _, _, p in out.frames)


def test_a_simulation_that_cannot_even_reset_is_rebuilt(running, monkeypatch):
    thread, out = running()
    broken = thread.sim

    def fail(*_):
        raise RuntimeError('broken state')

    monkeypatch.setattr(broken, '_step_once', fail)
    monkeypatch.setattr(broken, 'reset', fail)
    assert wait_for(lambda: thread.sim is not broken, 5.0)
    after = time.monotonic()
    assert wait_for(lambda: len(out.frames_after(after)) > 10, 5.0)
    assert any('rebuilding the simulation' in e for e in out.errors())


def test_every_request_is_answered_under_a_storm_of_them(running):
    thread, out = running(settings=StreamSettings(publish_rate_hz=60.0))
    sim0 = thread.sim
    bands = [FilterBand('lowpass', 0, 12, 'hz'), FilterBand('highpass', 10, 0, 'hz'),
             FilterBand('bandpass', 5, 40, 'hz'), FilterBand()]
    requests, lock = [], threading.Lock()

    def submit(make, count, pause_s):
        for k in range(count):
            request = make(k)
            with lock:
                requests.append(request)
            thread.submit(request)
            time.sleep(pause_s)

    makers = [
        (lambda k: ChangeBand(band=bands[k % 4], transition_s=0.2), 100, 0.02),
        (lambda k: Reset() if k % 2 else Pause(paused=k % 4 == 0), 60, 0.03),
        (lambda k: ReplaceSimulation(simulation=rebuild(
            sim0.model, sim0.basis, SimulationConfig(method=('full', 'modal')[k % 2]))),
         10, 0.15),
    ]
    workers = [threading.Thread(target=submit, args=m) for m in makers]
    for w in workers:
        w.start()
    for w in workers:
        w.join()
    thread.submit(Pause(paused=False))
    # a busy machine may take long over a storm: answered is what counts (the node's services
    # answer in time however long this takes: test_node_services)
    assert wait_for(lambda: all(r.answered for r in requests), 60.0), (
        sum(not r.answered for r in requests), out.logs[:5])
    assert all(r.applied for r in requests), [r.message for r in requests if not r.applied]
    after = time.monotonic()
    assert wait_for(lambda: len(out.frames_after(after)) > 10, 5.0)
    assert out.errors() == []
    assert all(np.isfinite(p).all() for _, _, p in out.frames)


def test_stopping_answers_the_requests_still_queued():
    sim = build_simulation(load_scene('sheet_10x10'), SimulationConfig())
    thread = SimulationThread(sim, Recorder(), StreamSettings, rebuild=lambda: sim)
    pending = thread.submit(Reset())
    thread.stop()
    assert pending.answered and not pending.applied
    assert pending.message == 'the node is shutting down'


def test_as_fast_as_possible_fills_each_frame_with_steps(running):
    """
    realtime_factor 0.

    As many steps as fit between frames, so the achieved factor follows the step cost (dt / step
    time), not one step per frame.
    """
    scene = variant('sheet_10x10', anchor_motion=[])
    sim = build_simulation(scene, SimulationConfig(band=FilterBand('lowpass', 0, 20, 'hz')))
    thread, out = running(sim, StreamSettings(publish_rate_hz=30.0, realtime_factor=0.0))
    start_wall, start_sim = time.monotonic(), thread.sim.time
    time.sleep(2.5)
    achieved = (thread.sim.time - start_sim) / (time.monotonic() - start_wall)
    step_s = np.median([r.step_us for _, r in out.reports if r.step_us > 0]) * 1e-6
    possible = sim.dt / step_s
    assert achieved > 0.4 * possible, (achieved, possible)
    steps_per_frame = achieved / 30.0 / sim.dt
    assert steps_per_frame > 20  # one step per frame would give 0.015 of real time


def test_band_changes_queued_together_build_only_the_last():
    sim = build_simulation(load_scene('sheet_10x10'), SimulationConfig())
    out = Recorder()
    thread = SimulationThread(sim, out, StreamSettings, rebuild=lambda: sim)
    first = thread.submit(ChangeBand(band=FilterBand('lowpass', 0, 12, 'hz'),
                                     changed={'filter.type': 'lowpass', 'filter.high_hz': 12.0}))
    second = thread.submit(ChangeBand(band=FilterBand('lowpass', 0, 20, 'hz'),
                                      changed={'filter.high_hz': 20.0}))
    thread.start()
    try:
        assert first.wait(5.0) and second.wait(5.0)
        assert 'superseded by lowpass <= 20 Hz' in first.message
        assert thread.sim.band == FilterBand('lowpass', 0, 20, 'hz')
        # one change recorded, with every parameter the two changed
        assert out.changes == [{'filter.type': 'lowpass', 'filter.high_hz': 20.0}]
    finally:
        thread.stop()


def test_clicks_queued_together_pull_toward_the_last_only_and_record_only_it():
    sim = build_simulation(variant('sheet_10x10', anchor_motion=[]), SimulationConfig())
    out = Recorder()
    thread = SimulationThread(sim, out, StreamSettings, rebuild=lambda: sim)
    # below the sheet (off the object): each would pull the particle nearest to it
    clicks = [thread.submit(_click_input(x, -1.5)) for x in (0.0, 0.45, 0.9)]
    thread.start()
    try:
        assert all(click.wait(5.0) for click in clicks)
        assert all('superseded by a newer clicked_point' in c.message for c in clicks[:2])
        assert clicks[2].message.startswith('pulling particle')
        assert thread.sim.pull.target[0] == 0.9
        # what acted, and only that
        assert out.inputs == [('/clicked_point', clicks[2].received)]
    finally:
        thread.stop()


def test_a_faster_publish_rate_takes_effect_at_once():
    """0.1 Hz then 60 Hz: frames at the new rate now, not after the old ten-second period."""
    sim = build_simulation(load_scene('sheet_10x10'), SimulationConfig())
    settings = {'rate': 0.1}
    out = Recorder()
    thread = SimulationThread(sim, out, lambda: StreamSettings(publish_rate_hz=settings['rate']),
                              rebuild=lambda: sim)
    thread.start()
    try:
        assert wait_for(lambda: len(out.frames) >= 1, 5.0)
        time.sleep(0.5)                                   # now inside the ten-second wait
        changed = time.monotonic()
        settings['rate'] = 60.0
        thread.settings_changed()
        old_period = 10.0
        assert wait_for(lambda: len(out.frames_after(changed)) >= 10, old_period / 2), (
            'the old period was waited out')
    finally:
        thread.stop()


def test_a_divergence_that_comes_back_every_time_is_held_and_reported_once(
        running, monkeypatch):
    """The same input again and again must not loop through divergences forever."""
    from modal_spring_ros.core.simulations import DivergenceError
    from modal_spring_ros.ros.stream.divergence_streak import MAX_RECOVERIES
    thread, out = running()
    sim = thread.sim
    real = sim._step_once

    def diverging():
        if sim.steps >= 20:                   # every run diverges soon after it starts
            raise DivergenceError('non-finite acceleration', sim.time, sim.steps)
        real()

    monkeypatch.setattr(sim, '_step_once', diverging)
    assert wait_for(lambda: thread.held, 5.0)
    held_logs = [m for level, m in out.logs if level == 'error']
    time.sleep(1.5)                           # held: no more divergences, no more logs
    assert [m for level, m in out.logs if level == 'error'] == held_logs
    assert len(held_logs) == MAX_RECOVERIES and 'holding at rest' in held_logs[-1]
    assert out.errors()[-1] == thread.held    # /diagnostics keeps saying it
    click = _click_input(0.3, -0.5)
    thread.submit(click)
    assert click.wait(2.0) is False and 'refused' in click.message
    monkeypatch.setattr(sim, '_step_once', real)
    reset = thread.submit(Reset())
    assert reset.wait(2.0) and not thread.held
    after = time.monotonic()
    assert wait_for(lambda: len(out.frames_after(after)) > 10, 5.0)


def _click(x: float, z: float):
    from geometry_msgs.msg import PointStamped
    message = PointStamped()
    message.header.frame_id = 'world'
    message.point.x, message.point.z = x, z
    return message


def _click_input(x: float, z: float) -> TakeInput:
    return TakeInput(kind=CLICKED_POINT, received=_click(x, z), values={
        'interaction.stiffness': 50.0, 'interaction.max_force_n': 5.0, 'interaction.hold_s': 1.0,
        'interaction.radius': 0.0})


def test_settings_changed_between_frames_keeps_the_frames_on_their_grid():
    """A slider dragged (a setting every few ms) neither adds frames nor delays them."""
    sim = build_simulation(load_scene('sheet_10x10'), SimulationConfig())
    out = Recorder()
    thread = SimulationThread(sim, out, lambda: StreamSettings(publish_rate_hz=30.0),
                              rebuild=lambda: sim)
    thread.start()
    try:
        assert wait_for(lambda: len(out.frames) >= 3, 5.0)
        start = time.monotonic()
        while time.monotonic() < start + 2.0:
            thread.settings_changed()
            time.sleep(0.007)
        gaps = np.diff([wall for wall, _, _ in out.frames_after(start)])
    finally:
        thread.stop()
    assert 40 <= gaps.size <= 65, gaps.size          # 2 s at 30 Hz: 60 frames, none added
    assert np.median(gaps) == pytest.approx(1 / 30.0, rel=0.15)
    assert np.percentile(gaps, 10) > 0.5 / 30.0, np.sort(gaps)[:5]  # no frame sent early


def test_a_run_that_cannot_step_in_real_time_keeps_its_frame_rate(running, monkeypatch):
    """Steps costing twice real time: the run slows (reported), the frames keep their rate."""
    sim = build_simulation(variant('sheet_10x10', anchor_motion=[]), SimulationConfig())
    real = sim._step_once
    step_cost = 2.0 * sim.dt  # wall seconds a step takes: half of real time at most

    def slow_step():
        time.sleep(step_cost)
        real()

    monkeypatch.setattr(sim, '_step_once', slow_step)
    thread, out = running(sim, StreamSettings(publish_rate_hz=30.0))
    start_wall, start_sim = time.monotonic(), thread.sim.time
    time.sleep(2.0)
    achieved = (thread.sim.time - start_sim) / (time.monotonic() - start_wall)
    gaps = np.diff([wall for wall, _, _ in out.frames_after(start_wall)])
    assert 0.05 < achieved < 0.55, achieved
    assert np.median(gaps) < 1.3 / 30.0, np.median(gaps)   # not a frame every other period
    reported = [r.achieved_rtf for _, r in out.reports if r.window_valid]
    assert reported and reported[-1] < 0.6, reported


def test_modes_begun_or_ready_are_reported_at_once_not_a_period_later(monkeypatch):
    """A change that starts or stops computing modes goes out on /diagnostics at once."""
    monkeypatch.setattr(simulation_thread, 'DIAGNOSTICS_PERIOD_S', 1e6)   # no periodic report
    computing = threading.Event()
    sim = build_simulation(load_scene('sheet_10x10'), SimulationConfig())
    out = Recorder()
    thread = SimulationThread(sim, out, StreamSettings, rebuild=lambda: sim,
                              computing_modes=computing.is_set)
    thread.start()
    try:
        assert wait_for(lambda: len(out.frames) > 3, 5.0)
        assert out.reports == []
        computing.set()
        assert wait_for(lambda: len(out.reports) == 1, 10.0)
        assert out.reports[0][1].computing_modes
        time.sleep(0.2)                     # nothing changed since: no second report
        assert len(out.reports) == 1
        computing.clear()
        assert wait_for(lambda: len(out.reports) == 2, 10.0)   # (its window had them computed)
        time.sleep(0.2)
        assert len(out.reports) == 2 and out.errors() == []
    finally:
        thread.stop()

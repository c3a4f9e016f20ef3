"""
Between watched windows: a motion that outgrows what was measured, an error on its way up.

``sheet_10x10`` shaken ever harder near its vertical mode (3 cm at 9.5 Hz, ramped in over 12 s):
its plan keeps within half a percent while the motion is within a few times what its pilot saw,
then passes twice the tolerance within a second as the sheet goes into large deformation.
Watched at an interval longer than the run, only the sentinel (a window as soon as the motion
outgrows the measured) and a window's trend (the next window at once where the error is heading
beyond the tolerance) can catch it, and they must catch it as it passes 2 T.
"""
from __future__ import annotations

from modal_spring_ros.bench.accuracy.watched import (NEVER_S, plan_of, quarter_errors, RUN_S,
                                                     shaken_harder, TOLERANCE)
from modal_spring_ros.core.auto.measured_error import (WINDOW_ALLOWANCE, window_errors,
                                                       worst_window)
from modal_spring_ros.core.auto.watch.run_watch import HEADING, RunWatch, TOOK_INPUT
from modal_spring_ros.core.auto.watch.sentinel import RISE
from modal_spring_ros.core.auto.watch.windows import WatchedWindow
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.loads.pull import make_pull
from modal_spring_ros.core.simulations import Simulation
from modal_spring_ros.runs.run import record
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest


@pytest.mark.slow
def test_a_motion_that_outgrows_the_measured_is_caught_as_its_error_passes_2_t():
    """
    Never due, the watch still measures the plan, from a window the sentinel starts.

    The next follows at once while the error heads beyond the tolerance, until one falls back.
    (With no sentinel, no window at all: the interval is longer than the run.)
    """
    plan = plan_of(shaken_harder())
    assert plan.method == 'modal'
    errors = quarter_errors(plan, RUN_S)
    quarter_s = RUN_S / errors.size
    passes = int(np.argmax(errors > WINDOW_ALLOWANCE * TOLERANCE))
    assert errors[passes] > WINDOW_ALLOWANCE * TOLERANCE and passes * quarter_s > 5.0
    assert errors[:passes // 2].max() < TOLERANCE         # within it for more than a window
    seen = []
    watch = RunWatch(plan.watch_reference, NEVER_S)
    run = record(plan.with_dt(plan.dt), RUN_S, frame_every=10, watch=watch,
                 on_watch=lambda window, sim: seen.append((window, sim)))
    (early, kept), (caught, fallback) = seen[0], seen[-1]
    # the first window was started by the motion, beyond RISE times what the pilot measured
    assert early.cause.endswith('times the largest measured') and early.within
    assert kept.method == 'modal'                     # within: the plan goes on
    assert float(early.cause.split(' ')[2]) > RISE
    assert plan.watch_reference.window_s < early.start_s < passes * quarter_s
    # the windows that follow it come at once while the error heads beyond the tolerance
    for before, after in zip(seen, seen[1:]):
        assert before[0].rising and after[0].cause == HEADING
        assert after[0].start_s == pytest.approx(before[0].start_s + before[0].window_s,
                                                 abs=plan.dt)
    # the last is beyond the promise: the run fell back within the first quarter second its
    # error passes 2 T (windows are measured whole: a quarter's resolution, not a sample's)
    assert not caught.within and caught.start_s < (passes + 1) * quarter_s
    assert fallback.method == 'full' and run.method == 'full'
    assert watch.sentinel.started >= 1


def test_a_steady_run_starts_no_window_early():
    """sheet_10x10 as built in (a steady shake): the sentinel stays quiet for 20 s."""
    plan = plan_of(load_scene('sheet_10x10'))
    watch = RunWatch(plan.watch_reference, NEVER_S)
    seen = []
    record(plan.with_dt(plan.dt), 20.0, frame_every=50, watch=watch, keep_frames=False,
           on_watch=lambda window, sim: seen.append(window))
    assert seen == [] and watch.sentinel.started == 0
    assert watch.sentinel.envelope[0] > 0.0 and watch.describe().endswith('(none yet)')


def test_a_pull_taken_after_the_measured_span_began_is_not_counted_as_measured():
    """
    A user's pull during the pilot's span is not what the pilot measured: it starts a window.

    Told of it (``took_input``), the watch measures the pulled run at once; not told, the pull
    (a corner held 5 N aside moves the sheet less than twice what its pilot saw) passes as
    measured and no window comes in the run.
    """
    plan = plan_of(load_scene('sheet_10x10'))
    corner = int(np.argmin(plan.model.scene.rest_positions[:, 0]
                           + plan.model.scene.rest_positions[:, 2]))
    for told in (True, False):
        sim, watch, seen = plan.with_dt(plan.dt), RunWatch(plan.watch_reference, NEVER_S), []
        while sim.time < 4.0 and not seen:
            sim, window = watch.before_step(sim)
            if window is not None:
                seen.append(window)
            if sim.pull is None and sim.time >= 1.0:
                sim.start_pull(make_pull(sim.model, corner, [-0.3, 0.0, -1.2], 50.0, 5.0,
                                         sim.time, 60.0))
                if told:
                    watch.took_input(sim)
            sim.step()
        if told:
            assert len(seen) == 1 and seen[0].start_s == pytest.approx(1.0, abs=2 * plan.dt)
            assert seen[0].cause == TOOK_INPUT and not seen[0].within   # off its promise
        else:
            assert seen == []


def test_a_window_within_the_tolerance_overall_but_beyond_twice_it_in_a_quarter_is_beyond():
    calm = WatchedWindow(3.0, 3.0, 0.006, TOLERANCE, 'the full run', worst=0.012, heading=0.007)
    burst = WatchedWindow(3.0, 3.0, 0.006, TOLERANCE, 'the full run', worst=0.025, heading=0.007)
    heading = WatchedWindow(3.0, 3.0, 0.006, TOLERANCE, 'the full run', worst=0.012,
                            heading=0.015)
    assert calm.within and not calm.rising and 'worst' not in calm.describe()
    assert not burst.within and '2.50% over its worst 0.25 s' in burst.describe()
    assert heading.within and heading.rising
    twin = WatchedWindow(3.0, 0.25, float('nan'), TOLERANCE, '', growth=0.1)
    assert twin.within and not twin.rising


def test_the_windows_errors_are_the_worst_window_s_windows():
    rng = np.random.default_rng(3)
    reference = rng.normal(size=(120, 6))
    run = reference * (1.0 + 0.01 * np.linspace(0.0, 3.0, 120))[:, None]
    difference = np.einsum('ij,ij->i', run - reference, run - reference)
    motion = np.einsum('ij,ij->i', reference, reference)
    errors = window_errors(difference, motion, 0.025)
    assert errors.size == 12 and np.all(np.diff(errors) > 0.0)        # it grows, window by window
    assert errors.max() == pytest.approx(worst_window(run, reference, 0.025))
    assert 0.0275 < errors[-1] < 0.03           # the growth over its last tenth of the samples
    difference[5] = np.inf
    assert window_errors(difference, motion, 0.025)[0] == np.inf


@pytest.mark.parametrize('basis', ['rest', 'derivatives'])
def test_a_modal_run_s_motion_size_from_its_coordinates_is_the_physical_one(basis):
    """Its coordinates are mass-orthonormal: ``q^T q`` is ``u^T M u``, without mapping ``u``."""
    sim = build_simulation(shaken_harder(), SimulationConfig(
        band=FilterBand('lowpass', 0, 15, 'index'), basis=basis))
    sim.step(600)
    sizes = sim.motion_size()
    physical = Simulation.motion_size(sim)           # the contract's own, from u and v
    assert sizes[0] > 0.0 and sizes[1] > 0.0
    assert sizes == pytest.approx(physical, rel=1e-9)


def test_a_stream_of_inputs_is_watched_no_more_often_than_the_budget_affords():
    """Inputs every half second on a watch whose budget affords a window every 4 s: two."""
    plan = plan_of(load_scene('sheet_10x10'))
    reference = plan.watch_reference
    watch = RunWatch(reference, NEVER_S, budget=reference.window_s * reference.shadow_work / 4.0)
    assert watch.least_s == pytest.approx(4.0) and watch.interval_s == NEVER_S
    sim, starts, told = plan.with_dt(plan.dt), [], -1
    while sim.time < 7.0:
        if int(sim.time / 0.5) > told:                  # a user's input every half second
            told = int(sim.time / 0.5)
            watch.took_input(sim)
        sim, window = watch.before_step(sim)
        if window is not None:
            starts.append((window.start_s, window.cause))
        sim.step()
    assert [cause for _, cause in starts] == [TOOK_INPUT, TOOK_INPUT]
    assert [start for start, _ in starts] == pytest.approx([0.0, 4.0], abs=2 * plan.dt)


@pytest.mark.slow
def test_the_full_run_fallen_back_to_is_watched_by_its_twin():
    """
    The shaken sheet over 20 s, watched every 3 s: after its fallback at 6 s, the full run.

    Its step was measured over the pilot's window only; in the large deformation after 7.5 s a
    hair's difference grows there (the full run at that step is 3-7 % off its converged
    reference): its twin's windows, every 3 s from the fallback, say so.
    """
    plan = plan_of(shaken_harder())
    watch = RunWatch(plan.watch_reference, 3.0, run_s=20.0)
    seen = []
    run = record(plan.with_dt(plan.dt), 20.0, frame_every=10, watch=watch, keep_frames=False,
                 on_watch=lambda window, sim: seen.append((window, sim.method)))
    fell = [k for k, (window, _) in enumerate(seen) if not window.within]
    assert len(fell) == 1 and run.method == 'full'
    caught = seen[fell[0]][0]
    then = watch.then
    assert then is not None and then.reference.reference is None     # its twin alone
    twins = [window for window, method in seen[fell[0] + 1:]]
    assert len(twins) == then.windows >= 4 and all(method == 'full' for _, method in seen[3:])
    assert all(not window.against and not window.measured for window in twins)
    assert [window.start_s for window in twins[:4]] == pytest.approx(
        [caught.start_s + 3.0 * k for k in range(1, 5)], abs=0.01)
    assert then.amplifying is not None and then.amplifying.start_s > 7.5
    assert 'amplifying first' in then.describe() or then.last.amplifying

"""
An automatic plan watched while it runs: its error measured again from the run's own state.

The pilot measures a plan from rest; a user's pull takes the sheet where the plan was never
measured. The watch's window from the run's state must say what the live run's error then is
(against the full run from the same state), catch the pull, and fall back to the full run
continuing from the same state.
"""
from __future__ import annotations

from modal_spring_ros.core.auto.measured_error import on_samples, trajectory_error
from modal_spring_ros.core.auto.watch.amplification import AMPLIFYING_PER_S
from modal_spring_ros.core.auto.watch.run_watch import RunWatch, watch_of
from modal_spring_ros.core.auto.watch.twin_watch import watchable
from modal_spring_ros.core.config import ConfigError, SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.loads.pull import make_pull
from modal_spring_ros.core.simulations import RunState
from modal_spring_ros.runs.run import record
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest

TOLERANCE = 0.01
#: watched every this many simulated seconds (the work share's stretch left out: the tests
#: watch more often than a run would)
INTERVAL_S = 2.0


@pytest.fixture(scope='module')
def plan():
    """``sheet_10x10``'s automatic plan at 1 % (rest modes, refreshed forces)."""
    return build_simulation(load_scene('sheet_10x10'),
                            SimulationConfig(auto=True, tolerance=TOLERANCE))


def fresh(plan):
    sim = plan.with_dt(plan.dt)
    sim.watch_reference = plan.watch_reference
    return sim


def pull_hard(sim) -> None:
    """Pull the sheet's lower corner 0.3 m aside with 5 N (half its weight) for a minute."""
    corner = int(np.argmin(sim.model.scene.rest_positions[:, 0]
                           + sim.model.scene.rest_positions[:, 2]))
    sim.start_pull(make_pull(sim.model, corner, [-0.3, 0.0, -1.2], 50.0, 5.0, sim.time, 60.0))


def test_the_watch_measures_what_the_live_run_does_from_its_state(plan):
    """The window's error is the live run's error against the full run from the same state."""
    sim = fresh(plan)
    reference = plan.watch_reference
    assert reference.against == 'the full run' and reference.shared == 1.0
    watch = RunWatch(reference, INTERVAL_S)
    window = None
    while window is None:
        sim.step()
        if sim.time > 1.0 and sim.pull is None:
            pull_hard(sim)
        window = watch.advance(sim)
    # the live run from the window's start, against a finer full run from the same state
    start = RunState.of(sim)
    per = round(reference.sample_s / sim.dt)
    live = np.empty((reference.samples, sim.model.n_free_dof))
    for k in range(reference.samples):
        sim.step(per)
        live[k] = sim.displacement()
    truth_run = on_samples(reference.reference(), reference.sample_s,
                           reference.reference().dt / 2)
    truth_run.take_over(start)
    truth = np.empty_like(live)
    for k in range(reference.samples):
        truth_run.step(round(reference.sample_s / truth_run.dt))
        truth[k] = truth_run.displacement()
    achieved = trajectory_error(live, truth)
    assert window.start_s == pytest.approx(start.time)
    assert achieved > TOLERANCE                         # the pull took the plan off its promise
    assert window.error == pytest.approx(achieved, rel=0.1)
    assert not window.within and 'against the full run' in window.describe()


def test_a_pull_beyond_the_plan_is_caught_and_the_run_falls_back_to_the_full_run(plan):
    sim = fresh(plan)
    watch = RunWatch(plan.watch_reference, INTERVAL_S)
    seen = []

    def on_watch(window, now):
        seen.append((window, now))
        if len(seen) == 1:
            pull_hard(now)      # after a window within the tolerance, the user pulls

    run = record(sim, 3 * INTERVAL_S + 0.5, frame_every=10, watch=watch, on_watch=on_watch)
    (calm, kept), (pulled, fallback) = seen[:2]
    # then the full run is watched by its twin alone, an interval on
    assert [(window.against, now) for window, now in seen[2:]] == [('', fallback)]
    assert seen[2][0].start_s == pytest.approx(3 * INTERVAL_S, abs=0.01)
    assert calm.within and 0.0 < calm.error <= TOLERANCE and kept is sim
    # the plan's twin was stepped beside it: a sheet swinging amplifies no difference
    assert calm.growth < 0.25 * AMPLIFYING_PER_S and not calm.amplifying
    assert calm.start_s == pytest.approx(INTERVAL_S, abs=sim.dt)
    assert not pulled.within and pulled.error > TOLERANCE
    assert pulled.start_s == pytest.approx(2 * INTERVAL_S, abs=sim.dt)
    # the full run went on from the plan's state at the window's start, on the frame grid
    assert fallback.method == 'full' and run.simulation is fallback and run.method == 'full'
    assert fallback.time == pytest.approx(3 * INTERVAL_S + 0.5, abs=fallback.dt)
    frame_s = 10 * sim.dt
    assert np.allclose(np.diff(run.t), frame_s, atol=0.51 * fallback.dt)
    assert np.isfinite(run.positions).all() and not run.diverged
    assert watch.describe().startswith('2 windows: last ')


def test_the_fallback_continues_from_the_run_s_state():
    sim = build_simulation(load_scene('sheet_10x10'),
                           SimulationConfig(auto=True, tolerance=TOLERANCE))
    sim.step(500)
    watch = RunWatch(sim.watch_reference)
    fallback = watch.fallback(sim, 0.02)
    assert fallback.time == sim.time and fallback.method == 'full'
    assert 0.02 / fallback.dt == pytest.approx(round(0.02 / fallback.dt))
    assert np.allclose(fallback.displacement(), sim.displacement(), atol=1e-12)
    assert np.allclose(fallback.velocity(), sim.velocity(), atol=1e-12)


def test_watching_at_the_default_interval_costs_a_bounded_share_of_the_run(plan):
    """
    Asked for no interval, the watch costs at most a quarter of the plan's work.

    An interval asked for is kept; a budget of the caller's own stretches it.
    """
    reference = plan.watch_reference
    ratio = reference.shadow_work / reference.plan_work
    assert ratio > 2.0                  # the converged full run costs more than the plan
    assert watch_of(plan, None).interval_s == pytest.approx(
        max(10.0, reference.window_s * ratio / 0.25))
    assert watch_of(plan, 1.0).interval_s == 1.0 and watch_of(plan, 0.0) is None
    # a budget of its own: at most 1e5 us of work per simulated second
    assert RunWatch(reference, 1.0, budget=1e5).interval_s == pytest.approx(
        max(1.0, reference.window_s * reference.shadow_work / 1e5))


def test_only_a_clamp_that_moves_as_a_function_of_time_is_watched():
    scene = load_scene('sheet_10x10')
    assert watchable(build_simulation(scene, SimulationConfig()).model)
    follows = build_simulation(scene, SimulationConfig(anchor='topic'))
    assert not watchable(follows.model)


def test_a_plan_that_is_not_automatic_has_nothing_to_watch():
    sim = build_simulation(load_scene('chain_2'), SimulationConfig())
    assert sim.watch_reference is None and sim.pilot is None


@pytest.mark.parametrize('value', [-1.0, float('nan'), float('inf')])
def test_a_bad_interval_is_refused_by_name(value):
    with pytest.raises(ConfigError, match='--watch'):
        SimulationConfig(watch_s=value).validate({'watch_s': '--watch'})


def test_recordings_made_before_runs_were_watched_are_not_watched():
    data = SimulationConfig(auto=True).to_dict()
    del data['watch_s']
    assert SimulationConfig.from_dict(data).watch_s == 0.0

"""
The simulation thread's watch over an automatic plan, without DDS.

What it watches (an automatic plan whose clamp is a function of time, until a band is set on it
by hand), when it falls back (once, with the settings that rebuild the fallback), and that a
failing watch costs the run nothing.
"""
from __future__ import annotations

import dataclasses
import math

from modal_spring_ros.core.auto.watch import amplification
from modal_spring_ros.core.auto.watch.run_watch import TOOK_INPUT
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation, rebuild
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.ros.stream.plan_watch import PlanWatch
from modal_spring_ros.scenes.resources import load_scene
import pytest

CONFIG = SimulationConfig(auto=True, tolerance=0.01)


@pytest.fixture(scope='module')
def plan():
    return build_simulation(load_scene('sheet_10x10'), CONFIG)


def run_of(plan, reference=None):
    """Return a fresh run of ``plan`` (at rest), watched against ``reference`` (its own)."""
    sim = plan.with_dt(plan.dt)
    sim.watch_reference = reference or plan.watch_reference
    return sim


def step_watched(watch: PlanWatch, sim, seconds: float, interval_s: float = 1.0) -> None:
    while sim.time < seconds:
        sim.step()
        watch.step(sim, interval_s, math.inf)


def test_a_window_within_the_tolerance_is_reported_and_nothing_falls_back(plan):
    fallen = []
    watch = PlanWatch(lambda window, settings: fallen.append((window, settings)))
    assert watch.report() == {'watched': 'off', 'watch_beyond': ''}
    sim = run_of(plan)
    step_watched(watch, sim, 1.5)
    report = watch.report()
    assert report['watched'].startswith('1 window: last ') and report['watch_beyond'] == ''
    assert 'against the full run' in report['watched'] and not fallen


def test_a_window_beyond_falls_back_once_with_the_settings_of_the_full_run(plan):
    fallen = []
    watch = PlanWatch(lambda window, settings: fallen.append((window, settings)))
    strict = dataclasses.replace(plan.watch_reference, tolerance=1e-6)   # nothing meets it
    sim = run_of(plan, strict)
    step_watched(watch, sim, 3.5)
    (window, settings), = fallen                              # once: the run is replaced
    assert window.error > 1e-6 and not window.within
    assert settings == {'auto': False, 'method': 'full', 'integrator': 'explicit',
                        'dt': pytest.approx(settings['dt'])} and settings['dt'] > 0.0
    # the settings rebuild the full run the pilot measured, at its step
    again = rebuild(sim.model, sim.basis, dataclasses.replace(CONFIG, **settings))
    assert again.method == 'full' and again.dt == pytest.approx(settings['dt'])
    report = watch.report()
    assert report['watch_beyond'].startswith('automatic plan beyond its tolerance 0.00%')
    assert report['watch_beyond'].endswith('; falling back to the full run')
    # the full run the fallback set is watched on by its twin alone, the plan no longer
    again.take_over(sim)
    step_watched(watch, sim, 3.6)
    assert watch.report()['watched'].startswith('automatic plan beyond')
    step_watched(watch, again, 3.7)
    assert again.watch_reference is not None and again.watch_reference.reference is None
    assert again.watch_reference.tolerance == 1e-6
    assert watch.report()['watched'] == ('every 1 s of the run: a 0.25 s window of its twin '
                                         'moved by a hair (none yet)')
    step_watched(watch, again, 5.0)
    assert watch.report()['watched'].startswith("1 window: last a hair's difference ")


def test_a_band_set_by_hand_is_no_longer_the_plan_and_is_not_watched(plan):
    watch = PlanWatch(lambda window, settings: None)
    sim = run_of(plan)
    sim.set_band(FilterBand('lowpass', 0.0, 10.0))
    watch.band_changed(sim)
    step_watched(watch, sim, 1.5)
    assert watch.report()['watched'] == 'off'


def test_an_interval_of_zero_and_a_plan_not_chosen_by_auto_are_not_watched(plan):
    watch = PlanWatch(lambda window, settings: None)
    step_watched(watch, run_of(plan), 1.5, interval_s=0.0)
    assert watch.report()['watched'] == 'off'
    plain = build_simulation(load_scene('sheet_10x10'), SimulationConfig())
    step_watched(watch, plain, 0.2)
    assert watch.report()['watched'] == 'off'


def test_a_watch_that_fails_is_said_and_the_run_goes_on(plan):
    def broken():
        raise RuntimeError('no reference today')
    watch = PlanWatch(lambda window, settings: None)
    sim = run_of(plan, dataclasses.replace(plan.watch_reference, reference=broken))
    step_watched(watch, sim, 1.5)
    assert sim.time >= 1.5 and watch.report()['watch_beyond'] == (
        "the automatic plan is no longer watched: RuntimeError('no reference today')")


def test_a_motion_that_amplifies_its_differences_is_a_warning_not_a_fallback(plan, monkeypatch):
    """Any growth counts as amplifying here: the window is reported, the run goes on."""
    monkeypatch.setattr(amplification, 'AMPLIFYING_PER_S', -math.inf)
    fallen = []
    watch = PlanWatch(lambda window, settings: fallen.append((window, settings)))
    sim = run_of(plan)
    step_watched(watch, sim, 2.5)
    report = watch.report()
    assert not fallen and report['watch_beyond'].startswith('automatic plan: watched ')
    assert report['watch_beyond'].endswith(amplification.UNBOUNDED)
    assert report['watched'].startswith('2 windows: last ')


def test_an_input_the_run_takes_starts_a_window_at_once(plan):
    """A user's input on the run watched starts a window (never due here), said as its cause."""
    watch = PlanWatch(lambda window, settings: None)
    sim = run_of(plan)
    step_watched(watch, sim, 1.0, interval_s=1000.0)
    watch.took_input(run_of(plan))                  # another run's input: not this watch's
    step_watched(watch, sim, 1.2, interval_s=1000.0)
    assert '(none yet)' in watch.report()['watched']
    watch.took_input(sim)
    step_watched(watch, sim, 1.3, interval_s=1000.0)
    report = watch.report()['watched']
    assert report.startswith('1 window: last ') and f'(started early: {TOOK_INPUT})' in report
    assert 'from t = 1.2' in report

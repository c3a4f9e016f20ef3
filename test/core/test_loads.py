"""
One seat for what acts on particles from outside: a toy load added from the test folder.

A wind (``toy_loads.Wind``) on a single oscillator follows the analytic step response in the
full and the modal run; the run holds its loads by name, a reset clears them, a hand-over and a
watch's shadow runs take them all; on a turning clamp the load stays in world directions.
"""
from __future__ import annotations

import math

from helpers import oscillator
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.loads.pull import make_pull
from modal_spring_ros.core.simulations import RunState
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest
from toy_loads import Wind

K, M, F = 400.0, 0.25, 2.0


@pytest.mark.parametrize('method', ['full', 'modal'])
def test_a_toy_load_gives_the_analytic_step_response(method):
    """
    x(t) = F / k (1 - cos(omega t)) for a force F applied from rest at t = 0.

    To the step's resolution: the load set on a run at rest enters with the first step (half a
    step late: at most ``omega dt / 2`` of the static sag).
    """
    sim = build_simulation(oscillator(K, M), SimulationConfig(method=method, dt=1e-4))
    sim.set_load('wind', Wind(np.array([F])))
    omega = math.sqrt(K / M)
    times, x = [], []
    for _ in range(50):
        sim.step(20)
        times.append(sim.time)
        x.append(sim.displacement()[0])
    expected = F / K * (1.0 - np.cos(omega * np.array(times)))
    np.testing.assert_allclose(x, expected, atol=0.5 * omega * 1e-4 * F / K * 1.05)
    assert max(x) == pytest.approx(2.0 * F / K, rel=1e-3)     # twice the static sag


def test_the_run_holds_its_loads_by_name_and_a_reset_clears_them():
    sim = build_simulation(load_scene('sheet_10x10'), SimulationConfig())
    wind = Wind(np.array([0.01, 0.0]))
    sim.set_load('wind', wind)
    sim.start_pull(make_pull(sim.model, 55, [0.3, 0.0, -0.4], 50.0, 5.0, 0.0, 1.0))
    assert set(sim.loads) == {'wind', 'pull'} and sim.pull is sim.loads['pull']
    with pytest.raises(ValueError, match="a wind load set as 'pull'"):
        sim.set_load('pull', wind)
    # a hand-over (a settings change) and a watch's shadow state take every load
    other = build_simulation(load_scene('sheet_10x10'), SimulationConfig(method='full'))
    sim.step(10)
    other.take_over(sim)
    assert other.loads == sim.loads and other.loads is not sim.loads
    assert RunState.of(sim).loads == sim.loads
    sim.set_load('wind', None)
    assert set(sim.loads) == {'pull'} and set(other.loads) == {'wind', 'pull'}
    sim.reset()
    assert sim.loads == {} and sim.pull is None


def test_a_load_ends_at_its_time_and_pushes_the_sheet_along_it():
    sim = build_simulation(load_scene('sheet_10x10'), SimulationConfig(method='full'))
    still = build_simulation(load_scene('sheet_10x10'), SimulationConfig(method='full'))
    sim.set_load('wind', Wind(np.array([0.005, 0.0]), until=0.05))
    sim.step(100)                                 # 0.05 s: a quarter of the first mode's period
    still.step(100)
    moved = sim.displacement() - still.displacement()
    assert moved[0::2].mean() > 1e-4              # pushed along +x (the scene's first axis)
    sim.step(1)
    still.step(1)
    assert not sim.loads['wind'].active(sim.time)
    # once it ended, both feel the same forces: the difference only carries on
    a = build_simulation(load_scene('sheet_10x10'), SimulationConfig(method='full'))
    a.take_over(sim)
    assert a._applied(lambda dofs: a.displacement()[dofs], a.time + a.dt) is None


def test_on_a_turning_clamp_the_load_stays_in_world_directions():
    """sheet_10x10_swing in the full and the modal run: the same wind, the same push."""
    runs = {}
    for method in ('full', 'modal'):
        sim = build_simulation(load_scene('sheet_10x10_swing'),
                               SimulationConfig(method=method, dt=2.5e-4))
        quiet = build_simulation(load_scene('sheet_10x10_swing'),
                                 SimulationConfig(method=method, dt=2.5e-4))
        sim.set_load('wind', Wind(np.array([0.0, 0.005])))
        sim.step(800)
        quiet.step(800)
        runs[method] = sim.positions() - quiet.positions()
    assert np.abs(runs['full']).max() > 1e-5
    np.testing.assert_allclose(runs['modal'], runs['full'], atol=2e-3 * np.abs(runs['full']).max())

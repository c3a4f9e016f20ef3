"""A wrench pushing the particles near a point: spread as it should be, bounded, exact in time."""
from __future__ import annotations

import math

from helpers import oscillator
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.loads.wrench import (default_radius, make_wrench, region, spread_wrench,
                                                WrenchError)
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest


def _moment(offsets: np.ndarray, forces: np.ndarray) -> np.ndarray:
    return np.cross(offsets, forces).sum(axis=0)


def test_the_spread_forces_add_up_to_the_wrench_with_the_least_squared_sum():
    rng = np.random.default_rng(7)
    offsets = rng.normal(size=(9, 3))
    force, torque = np.array([1.0, -2.0, 0.5]), np.array([0.3, 0.1, -0.7])
    spread = spread_wrench(offsets, force, torque)
    np.testing.assert_allclose(spread.sum(axis=0), force, atol=1e-12)
    np.testing.assert_allclose(_moment(offsets, spread), torque, atol=1e-12)
    # the least-norm solution of the same 6 x 27 system, solved directly
    rows = np.zeros((6, 27))
    for i, r in enumerate(offsets):
        rows[:3, 3 * i:3 * i + 3] = np.eye(3)
        rows[3:, 3 * i:3 * i + 3] = [[0, -r[2], r[1]], [r[2], 0, -r[0]], [-r[1], r[0], 0]]
    least = np.linalg.lstsq(rows, np.concatenate([force, torque]), rcond=None)[0]
    np.testing.assert_allclose(spread.ravel(), least, atol=1e-12)


def test_one_particle_carries_the_force_and_only_the_torque_it_can():
    spread = spread_wrench(np.zeros((1, 3)), np.array([0.0, 0.0, 2.0]), np.array([1.0, 0, 0]))
    np.testing.assert_allclose(spread, [[0.0, 0.0, 2.0]], atol=1e-12)


def test_the_region_is_the_free_particles_within_the_radius_or_the_nearest():
    sim = build_simulation(load_scene('sheet_10x10'), SimulationConfig(max_modes=20))
    positions = sim.positions()
    point = positions[55]
    spacing = float(np.linalg.norm(positions[56] - positions[55]))
    assert sorted(region(sim.model, positions, point, 1.01 * spacing)) == [45, 54, 55, 56, 65]
    # 5 m above: nothing within the radius; the nearest free one, below the clamped top row
    assert sim.model.scene.fixed[90:].all()
    assert list(region(sim.model, positions, point + [0, 0, 5.0], spacing)) == [85]
    fixed = int(sim.model.fixed_particles[0])
    assert fixed not in region(sim.model, positions, positions[fixed], 0.5 * spacing)


def test_a_wrench_beyond_the_caps_is_scaled_down_as_a_whole():
    sim = build_simulation(load_scene('sheet_10x10'), SimulationConfig(max_modes=20))
    wrench = make_wrench(sim.model, sim.positions(), sim.positions()[55], [30.0, 0, 40.0],
                         [0, 0.1, 0], radius=0.15, max_force=5.0, now=0.0, hold_s=1.0)
    assert wrench.capped
    np.testing.assert_allclose(wrench.force, [3.0, 0.0, 4.0])
    np.testing.assert_allclose(wrench.torque, [0, 0.01, 0])
    # a 2D sheet (x-z plane) takes the in-plane force and the torque about its normal (y)
    np.testing.assert_allclose(wrench.forces.sum(axis=0), [3.0, 4.0], atol=1e-12)
    torque = make_wrench(sim.model, sim.positions(), sim.positions()[55], [0, 0, 0],
                         [0, 10.0, 0], radius=0.15, max_force=5.0, now=0.0, hold_s=1.0)
    np.testing.assert_allclose(torque.torque, [0, 0.75, 0])


@pytest.mark.parametrize('change, message', [
    ({'force': [np.nan, 0, 0]}, 'force must be three finite'),
    ({'point': [0, 0]}, 'point must be three finite'),
    ({'radius': 0.0}, 'radius'), ({'hold_s': -1.0}, 'hold_s'),
    ({'max_force': math.inf}, 'max_force'),
])
def test_a_wrench_that_cannot_act_is_refused_by_name(change, message):
    sim = build_simulation(load_scene('sheet_10x10'), SimulationConfig(max_modes=20))
    args = {'point': [0.5, 0, -0.5], 'force': [1.0, 0, 0], 'torque': [0, 0, 0], 'radius': 0.1,
            'max_force': 5.0, 'now': 0.0, 'hold_s': 1.0}
    args.update(change)
    with pytest.raises(WrenchError, match=message):
        make_wrench(sim.model, sim.positions(), **args)


@pytest.mark.parametrize('method', ['full', 'modal'])
def test_a_constant_force_on_an_oscillator_moves_it_as_the_analytic_solution(method):
    """From rest, x(t) = F / k (1 - cos w t); back to free oscillation when the wrench ends."""
    k, m, force = 400.0, 0.25, 2.0
    sim = build_simulation(oscillator(k, m), SimulationConfig(method=method, dt=1e-4))
    w = math.sqrt(k / m)
    sim.start_wrench(make_wrench(sim.model, sim.positions(), [1.0, 0, 0], [force, 0, 0],
                                 [0, 0, 0], radius=0.01, max_force=10.0, now=0.0, hold_s=0.5))
    for _ in range(4000):                                  # 0.4 s, within the hold
        sim.step()
    x = sim.displacement()[0]
    assert x == pytest.approx(force / k * (1 - math.cos(w * sim.time)), abs=2e-5)
    sim.step(2000)                                         # 0.6 s: past the hold
    period_steps = round(2 * math.pi / w / sim.dt)
    samples = []
    for _ in range(period_steps):
        sim.step()
        samples.append(sim.displacement()[0])
    mean = float(np.mean(samples))
    assert abs(mean) < 0.02 * force / k        # oscillating about the rest again, not F / k
    sim.reset()
    assert sim.pull is None and sim.wrench is None


def test_the_default_radius_takes_a_particle_and_its_neighbours():
    sim = build_simulation(load_scene('sheet_10x10'), SimulationConfig(max_modes=20))
    positions = sim.positions()
    radius = default_radius(sim.model)
    assert sorted(region(sim.model, positions, positions[55], radius)) == [
        44, 45, 46, 54, 55, 56, 64, 65, 66]

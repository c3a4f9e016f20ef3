"""A person pulling a particle toward a point: bounded, whatever the point."""
from __future__ import annotations

from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.loads.pull import (make_pull, nearest_free_particle, PullError,
                                              REACH_MIN_M)
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest


@pytest.mark.parametrize('point', [(-1e308, 0.0, 0.0), (1e300, -1e300, 1e300),
                                   (0.45, 0.0, -5e3)])
def test_a_point_far_beyond_the_scene_pulls_like_one_at_its_reach(point):
    """A click at x = -1e308 once overflowed the pull (50 N/m x 1e308 = inf, inf x 0 = NaN)."""
    sim = build_simulation(load_scene('sheet_10x10'), SimulationConfig())
    particle = nearest_free_particle(sim.model, sim.positions(), np.array(point))
    pull = make_pull(sim.model, particle, point, 50.0, 5.0, sim.time, 1.0)
    rest = sim.model.rest
    size = max(float(np.max(rest.max(axis=0) - rest.min(axis=0))), REACH_MIN_M)
    assert np.isfinite(pull.target).all()
    assert np.all(pull.target >= rest.min(axis=0) - size - 1e-12)
    assert np.all(pull.target <= rest.max(axis=0) + size + 1e-12)
    sim.start_pull(pull)
    sim.step(400)                                      # 0.2 s of a pull at the capped force
    assert np.isfinite(sim.positions()).all()
    force = pull.force(sim.positions()[particle, sim.model.axes], sim.time)
    assert np.isfinite(force).all() and np.linalg.norm(force) <= 5.0 + 1e-9


def test_a_point_within_reach_is_kept_as_it_is():
    sim = build_simulation(load_scene('sheet_10x10'), SimulationConfig())
    point = np.array([0.3, 0.0, -0.4])
    pull = make_pull(sim.model, 55, point, 50.0, 5.0, 0.0, 1.0)
    np.testing.assert_array_equal(pull.target, point[sim.model.axes])


def test_a_non_finite_point_is_refused():
    sim = build_simulation(load_scene('sheet_10x10'), SimulationConfig())
    with pytest.raises(PullError, match='three finite coordinates'):
        make_pull(sim.model, 55, (np.nan, 0.0, 0.0), 50.0, 5.0, 0.0, 1.0)

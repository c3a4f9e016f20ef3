"""Clicks and wrenches without DDS: where they act, what ends them, what a capture keeps."""
from __future__ import annotations

from geometry_msgs.msg import PointStamped, WrenchStamped
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.loads.pull import nearest_free_particle
from modal_spring_ros.ros.frames.frame_tree import Transform
from modal_spring_ros.ros.inputs.input_kinds import (CLICKED_POINT, recorded_messages, WRENCH,
                                                     WrenchAt)
from modal_spring_ros.ros.parameters import PARAMETERS
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest

VALUES = {name: default for name, (default, _) in PARAMETERS.items()}


def wrench(frame_id: str = 'world', force=(1.0, 0.0, 0.0), torque=(0.0, 0.0, 0.0)):
    message = WrenchStamped()
    message.header.frame_id = frame_id
    f, t = message.wrench.force, message.wrench.torque
    f.x, f.y, f.z = (float(v) for v in force)
    t.x, t.y, t.z = (float(v) for v in torque)
    return message


@pytest.fixture
def sim():
    return build_simulation(load_scene('sheet_10x10'), SimulationConfig(max_modes=20))


def test_a_wrench_in_the_nodes_frame_acts_at_its_origin_and_is_kept_as_it_came(sim):
    message = wrench()
    assert WRENCH.refusal(message, VALUES, None) is None
    said = WRENCH.apply(sim, message, VALUES)
    nearest = nearest_free_particle(sim.model, sim.positions(), np.zeros(3))
    assert nearest in sim.wrench.particles and said.startswith('pushing')
    np.testing.assert_allclose(sim.wrench.force, [1.0, 0.0, 0.0])
    assert recorded_messages(WRENCH, message) == [('/wrench', message)]


def test_a_wrench_carried_through_tf_acts_at_its_frames_origin_on_the_nodes_axes(sim):
    # a frame half a turn about z from the world, at the middle particle: +x there is -x here
    middle = sim.positions()[55]
    carried = WRENCH.to_frame(wrench('pusher'), Transform(middle, (0.0, 0.0, 1.0, 0.0)),
                              'world')
    assert isinstance(carried, WrenchAt) and carried.header.frame_id == 'world'
    point, force, _ = carried.arrays()
    np.testing.assert_allclose(point, middle)
    np.testing.assert_allclose(force, [-1.0, 0.0, 0.0], atol=1e-12)
    WRENCH.apply(sim, carried, VALUES)
    assert 55 in sim.wrench.particles
    topics = [topic for topic, _ in recorded_messages(WRENCH, carried)]
    assert topics == ['/wrench_point', '/wrench']


def test_a_zero_wrench_ends_the_push_and_a_non_finite_one_is_refused(sim):
    WRENCH.apply(sim, wrench(), VALUES)
    assert sim.wrench is not None
    assert WRENCH.apply(sim, wrench(force=(0, 0, 0)), VALUES).startswith('wrench ended')
    assert sim.wrench is None
    assert WRENCH.refusal(wrench(torque=(0, np.nan, 0)), VALUES, None) == 'non-finite values'


def click(at) -> PointStamped:
    message = PointStamped()
    message.header.frame_id = 'world'
    message.point.x, message.point.y, message.point.z = (float(v) for v in at)
    return message


def test_clicks_pick_and_place(sim):
    """On the object: grab where it is; then any click takes the held particle there."""
    x = sim.positions()
    said = CLICKED_POINT.apply(sim, click(x[0]), VALUES)
    assert said.startswith('grabbed particle 0') and sim.pull.particle == 0
    np.testing.assert_allclose(sim.pull.target, x[0, sim.model.axes])
    CLICKED_POINT.apply(sim, click(x[55]), VALUES)              # on the object, elsewhere
    assert sim.pull.particle == 0
    np.testing.assert_allclose(sim.pull.target, x[55, sim.model.axes])
    CLICKED_POINT.apply(sim, click(x[0] + [0, 0, -0.5]), VALUES)    # off it: still the held one
    assert sim.pull.particle == 0
    CLICKED_POINT.apply(sim, click(x[0]), VALUES)               # on the held one: grabbed anew
    np.testing.assert_allclose(sim.pull.target, x[0, sim.model.axes])
    sim.start_pull(None)
    said = CLICKED_POINT.apply(sim, click(x[9] + [0.5, 0, 0]), VALUES)   # nothing held, off it
    assert said == 'pulling particle 9'

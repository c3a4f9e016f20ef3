"""The clamp that follows poses: a critically damped filter in closed form."""
from __future__ import annotations

import math
import pickle

from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.motion.clamp_follower import ClampFollower
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest

Q0 = np.array([0.0, 0.0, 0.0, 1.0])


def turn_z(angle: float) -> np.ndarray:
    return np.array([0.0, 0.0, math.sin(angle / 2), math.cos(angle / 2)])


def test_a_step_in_the_pose_is_followed_critically_damped():
    follower = ClampFollower(2.0, (0, 1))
    w = 2 * math.pi * 2.0
    follower.follow(0.0, [0.4, 0.0, 0.0], Q0)                  # the reference
    follower.follow(1.0, [0.5, 0.0, 0.0], turn_z(0.3))          # 0.1 m and 0.3 rad at t = 1
    for tau in (0.0, 0.05, 0.2, 1.0):
        frame = follower.frame(1.0 + tau)
        share = 1.0 - (1.0 + w * tau) * math.exp(-w * tau)       # x(t) / T from rest
        angle = math.atan2(frame.rotation[1, 0], frame.rotation[0, 0])
        assert abs(angle - 0.3 * share) < 1e-12
        # the first pose's position is carried by the turn and the shift
        np.testing.assert_allclose(frame.carry(np.array([[0.4, 0.0, 0.0]]))[0],
                                   [0.4 + 0.1 * share, 0.0, 0.0], atol=1e-12)
    # bounded acceleration, at most omega^2 times the jump (at the jump): of the first pose's
    # point, and of the turn
    frame = follower.frame(1.0)
    point = frame.rotation_acceleration @ np.array([0.4, 0.0, 0.0]) + frame.acceleration
    assert np.linalg.norm(point) <= w * w * 0.1 * (1 + 1e-6)
    assert abs(frame.rotation_acceleration[1, 0]) <= w * w * 0.3 * (1 + 1e-6)


def test_a_new_pose_changes_nothing_at_the_instant_it_comes():
    follower = ClampFollower(5.0, (0, 1, 2))
    follower.follow(0.0, [0.0, 0.0, 0.0], Q0)
    follower.follow(0.2, [0.1, 0.05, 0.0], turn_z(0.5))
    before = follower.frame(0.37)
    follower.follow(0.37, [-0.1, 0.0, 0.02], turn_z(-0.2))
    after = follower.frame(0.37)
    for name in ('rotation', 'translation'):
        np.testing.assert_allclose(getattr(after, name), getattr(before, name), atol=1e-12)
    for name in ('rotation_rate', 'velocity'):    # rates of the turn by central differences
        np.testing.assert_allclose(getattr(after, name), getattr(before, name), atol=1e-4)
    h = 1e-5                                     # the rates are the derivatives of the motion
    for t in (0.4, 0.6):
        d = (follower.frame(t + h).rotation - follower.frame(t - h).rotation) / (2 * h)
        np.testing.assert_allclose(d, follower.frame(t).rotation_rate, atol=1e-6)
        d = (follower.frame(t + h).velocity - follower.frame(t - h).velocity) / (2 * h)
        np.testing.assert_allclose(d, follower.frame(t).acceleration, atol=1e-4)


def test_bad_poses_are_named_and_a_2d_scene_follows_only_its_plane():
    follower = ClampFollower(5.0, (0, 1))
    assert follower.check([0.0, 0.0, 0.0], Q0, 1.0) is None       # the first pose, accepted
    follower.follow(0.0, [0.0, 0.0, 0.0], Q0)
    assert follower.check([math.nan, 0, 0], Q0, 1.0) == 'non-finite position or orientation'
    assert follower.check([0, 0, 0], 2 * Q0, 1.0).startswith('orientation is not a unit '
                                                             'quaternion (norm 2')
    assert follower.check([3.0, 0, 0], Q0, 1.0).startswith('position jumps 3 m')
    assert follower.check([0.5, 0, 0], Q0, 1.0) is None
    tilt = np.array([math.sin(0.2), 0.0, 0.0, math.cos(0.2)])   # about x: out of the plane
    follower.follow(0.0, [0.0, 0.0, 0.3], tilt)
    frame = follower.frame(10.0)
    np.testing.assert_allclose(frame.rotation, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(frame.translation, 0.0, atol=1e-12)


def test_a_follower_goes_to_the_worker_process_and_comes_back_the_same():
    follower = ClampFollower(5.0, (0, 1))
    follower.follow(0.0, [0.45, 0.0, 0.0], Q0)
    follower.follow(0.1, [0.5, 0.0, 0.0], turn_z(0.4))
    again = pickle.loads(pickle.dumps(follower))
    np.testing.assert_array_equal(again.frame(0.3).rotation, follower.frame(0.3).rotation)
    again.follow(0.3, [0.5, 0.0, 0.0], Q0)                     # its lock works


def test_the_first_pose_must_be_within_the_clamps_reach():
    """The clamp turns about the first pose: one at x = 1e6 swung the sheet through kilometres."""
    follower = ClampFollower(5.0, (0, 2), home=[0.45, 0.0, 0.0], reach_m=1.0)
    assert follower.check([1e6, 0.0, 0.0], Q0, 0.5).startswith(
        'the first pose is 1e+06 m from the clamp (at most 1 m')
    assert follower.check([0.5, 0.0, 0.2], Q0, 0.5) is None      # near the clamp: the first


def test_poses_are_judged_against_the_last_one_accepted_not_the_last_applied():
    """0.3 m steps at 50 Hz (each within 0.5 m) were locked out for good; none is now."""
    follower = ClampFollower(5.0, (0, 2), home=[0.0, 0.0, 0.0], reach_m=1.0)
    for k in range(20):                       # none applied (follow) in between: a fast stream
        assert follower.check([0.3 * k, 0.0, 0.0], Q0, 0.5) is None, k
    assert follower.check([0.3 * 19 + 0.6, 0.0, 0.0], Q0, 0.5).startswith('position jumps 0.6')


def test_orientation_jumps_are_bounded():
    """0, 90, 180 degrees at 50 Hz diverged the run: turns beyond anchor.max_turn_deg refused."""
    follower = ClampFollower(5.0, (0, 2), home=[0.0, 0.0, 0.0], reach_m=1.0)
    turn = math.radians(30.0)
    assert follower.check([0.0, 0.0, 0.0], Q0, 0.5, turn) is None
    quarter = np.array([0.0, math.sin(math.pi / 4), 0.0, math.cos(math.pi / 4)])  # 90 deg on y
    assert follower.check([0.0, 0.0, 0.0], quarter, 0.5, turn).startswith(
        'orientation turns 90 degrees from the last pose accepted (at most '
        'anchor.max_turn_deg = 30)')
    small = np.array([0.0, math.sin(math.pi / 24), 0.0, math.cos(math.pi / 24)])  # 15 deg
    assert follower.check([0.0, 0.0, 0.0], small, 0.5, turn) is None
    assert follower.check([0.0, 0.0, 0.0], -small, 0.5, turn) is None  # the same turn


def test_clearing_forgets_every_pose():
    """``~/reset``: back at the rest pose, and the next pose is judged as a first one."""
    follower = ClampFollower(5.0, (0, 2), home=[0.0, 0.0, 0.0], reach_m=1.0)
    assert follower.check([0.2, 0.0, 0.0], Q0, 0.5) is None
    follower.follow(0.0, [0.2, 0.0, 0.0], Q0)
    assert follower.check([0.6, 0.0, 0.0], Q0, 0.5) is None
    follower.follow(0.1, [0.6, 0.0, 0.0], Q0)
    assert np.linalg.norm(follower.frame(10.0).translation) > 0.3
    follower.clear()
    np.testing.assert_allclose(follower.frame(10.0).translation, 0.0, atol=1e-12)
    assert follower.check([5.0, 0.0, 0.0], Q0, 0.5).startswith('the first pose is 5 m')


def test_a_followed_clamp_is_the_runs_state_never_the_scenes():
    """
    Two runs of one scene follow poses each on their own; the scene stays the data it was.

    The follower is the run's model's motion (``model.motion``), handed to it when the run is
    built; the scene keeps its own ``anchor_motion``, and a run of the scene's motion built
    after them moves as the scene says.
    """
    scene = load_scene('sheet_10x10')
    first = build_simulation(scene, SimulationConfig(anchor='topic'))
    second = build_simulation(scene, SimulationConfig(anchor='topic'))
    assert isinstance(first.model.motion, ClampFollower)
    assert first.model.motion is not second.model.motion
    assert first.model.scene.anchor_motion is scene.anchor_motion
    first.model.motion.follow(0.0, [0.45, 0.0, -0.9], Q0)
    first.step(10)
    first.model.motion.follow(first.time, [0.47, 0.0, -0.9], Q0)   # 2 cm along x
    first.step(1000)
    second.step(1010)
    assert first.model.frame(first.time).translation[0] == pytest.approx(0.02, rel=0.01)
    np.testing.assert_allclose(second.model.frame(second.time).translation, 0.0, atol=1e-12)
    own = build_simulation(scene, SimulationConfig())
    assert own.model.motion is scene.anchor_motion
    own.step(200)                                        # the scene's shake, on its axes x, z
    np.testing.assert_allclose(own.model.frame(own.time).translation,
                               scene.anchor_motion.frame(own.time).translation[[0, 2]])
    assert np.linalg.norm(own.model.frame(own.time).translation) > 1e-5

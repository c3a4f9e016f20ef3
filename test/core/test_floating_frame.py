"""
Clamps that turn: the floating frame against the full run in the world.

The modal run writes the body in its clamp's frame and adds the frame's inertial loads; the
full run knows nothing of frames (it steps world positions with the clamp's particles put where
the clamp carries them). Their agreement checks the frame's algebra, each figure measured in
the test itself.
"""
from __future__ import annotations

import math

from helpers import variant
from modal_spring_ros.core.bases.basis import ModalBasis
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.motion.anchor_motion import (AnchorMotion, RotationComponent,
                                                        SineComponent)
from modal_spring_ros.core.simulations import FullSimulation, ModalSettings, ModalSimulation
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest

LOWPASS_0_14 = FilterBand('lowpass', 0, 14, 'index')


def deformation_errors(model, basis, sims: dict, duration: float, dt: float) -> dict:
    """
    Return each simulation's error against the full run in the world.

    The relative L2 error over the run of the displacement in the clamp's frame, against the full
    run in the world.
    """
    full = FullSimulation(model, basis, dt=dt)
    sums = {name: [0.0, 0.0] for name in sims}
    for _ in range(int(round(duration / dt))):
        full.step()
        f = full.displacement()
        for name, sim in sims.items():
            sim.step()
            d = sim.displacement() - f
            sums[name][0] += float(d @ d)
            sums[name][1] += float(f @ f)
    return {name: math.sqrt(a / b) for name, (a, b) in sums.items()}


def test_the_frames_rates_match_central_differences():
    motion = AnchorMotion(
        (SineComponent(0, 0.03, 1.3, 0.2, 0.4),),
        (RotationComponent(2, 0.7, 0.5, (0.4, -0.1, 0.2), 0.3, 0.6),
         RotationComponent(0, 0.4, 0.9, (0.0, 0.5, -0.3), 1.1, 0.0)))
    h = 1e-5
    for t in (0.1, 0.45, 0.8, 2.3):
        at, before, after = motion.frame(t), motion.frame(t - h), motion.frame(t + h)
        for value, rate, acceleration in (
                ('rotation', 'rotation_rate', 'rotation_acceleration'),
                ('translation', 'velocity', 'acceleration')):
            x0, x1, x2 = (getattr(f, value) for f in (before, at, after))
            np.testing.assert_allclose((x2 - x0) / (2 * h), getattr(at, rate), atol=1e-8)
            np.testing.assert_allclose((x2 - 2 * x1 + x0) / h**2, getattr(at, acceleration),
                                       atol=2e-4)
        np.testing.assert_allclose(at.rotation.T @ at.rotation, np.eye(3), atol=1e-14)


def test_a_turning_clamp_carries_its_particles_rigidly():
    model = MassSpringModel(load_scene('sheet_10x10_swing'))
    t = 1.75                                        # past the ramp, near the widest turn
    x = model.positions(np.zeros(model.n_free_dof), t)
    fixed = x[model.fixed_particles]
    rest = model.rest[model.fixed_particles]
    angle = math.radians(45.0) * math.sin(2 * math.pi * 0.5 * t)
    pivot = np.array([0.45, 0.0])  # (x, z): the sheet hangs in the x-z plane
    # a turn about +y: x -> x cos + z sin, z -> -x sin + z cos (rows, so the transpose)
    turned = (rest - pivot) @ np.array([[math.cos(angle), -math.sin(angle)],
                                        [math.sin(angle), math.cos(angle)]]) + pivot
    np.testing.assert_allclose(fixed, turned, atol=1e-15)
    # every particle rides along: distances in the rest shape are kept
    np.testing.assert_allclose(np.linalg.norm(x[1:] - x[0], axis=1),
                               np.linalg.norm(model.rest[1:] - model.rest[0], axis=1),
                               rtol=1e-13)


def test_a_full_run_in_the_world_shows_where_its_particles_are_without_the_frame():
    """
    A full run of a turning clamp steps world positions: it shows them as they are.

    They are the positions its displacement in the clamp's frame gives (the round trip it once
    took for every frame), to round-off, and its fixed particles are where the clamp carries
    them, in 2D and in 3D.
    """
    turn = {'rotation': 'y', 'amplitude_deg': 60.0, 'frequency_hz': 0.8, 'pivot': [0.0, 0.0, 0.0]}
    scenes = [load_scene('sheet_10x10_swing'), variant('cantilever_3d', anchor_motion=[turn])]
    for scene in scenes:
        model = MassSpringModel(scene)
        assert model.rotates
        full = FullSimulation(model, ModalBasis(model, initial_modes=8), dt=5e-4)
        full.step(1500)                                 # 0.75 s: turned and deformed
        shown = full.positions()
        through_frame = model.positions3(model.positions(full.displacement(), full.time))
        size = float(np.abs(shown).max())
        np.testing.assert_allclose(shown, through_frame, rtol=0, atol=1e-12 * size)
        frame = model.frame(full.time)
        np.testing.assert_allclose(
            shown[model.fixed_particles][:, model.axes],
            frame.carry(model.rest[model.fixed_particles]), rtol=0, atol=1e-15 * size)
        assert np.abs(full.displacement()).max() > 1e-6          # it did deform


@pytest.mark.slow
def test_every_mode_in_the_clamps_frame_converges_to_the_full_run_in_the_world():
    """
    Two independent discretisations of one motion.

    Their difference falls with the step (the Coriolis load is taken at the predicted velocity, a
    first-order error).
    """
    model = MassSpringModel(load_scene('sheet_10x10_swing'))
    basis = ModalBasis(model)
    errors = []
    for dt in (1e-3, 5e-4):
        every = ModalSimulation(model, basis, FilterBand(), ModalSettings(dt=dt))
        errors.append(deformation_errors(model, basis, {'all': every}, 2.0, dt)['all'])
    assert errors[1] < 2e-4
    assert errors[1] < 0.6 * errors[0], errors


def test_a_clamp_that_only_translates_runs_as_base_excitation_to_round_off(monkeypatch):
    """
    The frame's loads with ``R = I`` are today's base excitation.

    Forced through the frame path, the translating sheet_10x10 gives the same run.
    """
    model = MassSpringModel(load_scene('sheet_10x10'))
    basis = ModalBasis(model)
    today = ModalSimulation(model, basis, LOWPASS_0_14, ModalSettings(dt=5e-4, basis_kind='rest'))
    monkeypatch.setattr(MassSpringModel, 'rotates', property(lambda self: True))
    framed = ModalSimulation(model, basis, LOWPASS_0_14, ModalSettings(dt=5e-4, basis_kind='rest'))
    assert framed._frame is not None and today._frame is None
    for _ in range(10):
        today.step(200)
        framed.step(200)
        u = today.displacement()
        assert np.linalg.norm(framed.displacement() - u) <= 1e-12 * np.linalg.norm(u)
    np.testing.assert_allclose(framed.positions(), today.positions(), rtol=0, atol=1e-14)


@pytest.mark.slow
def test_sheet_swing_in_the_band_stays_within_two_percent_of_the_full_run():
    """
    The acceptance scene: the top row turning +-45 degrees at 0.5 Hz for 10 s.

    The 15-mode band in the clamp's frame (derivatives basis) against the full run; the same band
    with the turn left out (rest modes, the clamp's translation only: it has none) is reported
    beside it, as the world-position error.
    """
    model = MassSpringModel(load_scene('sheet_10x10_swing'))
    basis = ModalBasis(model)
    dt, duration = 5e-4, 10.0
    framed = ModalSimulation(model, basis, LOWPASS_0_14,
                             ModalSettings(dt=dt, basis_kind='derivatives'))
    still = MassSpringModel(variant('sheet_10x10_swing', anchor_motion=[]))
    left_out = ModalSimulation(still, ModalBasis(still), LOWPASS_0_14, ModalSettings(dt=dt))
    full = FullSimulation(model, basis, dt=dt)
    sums = np.zeros(5)
    for _ in range(int(round(duration / dt))):
        for sim in (full, framed, left_out):
            sim.step()
        f = full.displacement()
        d = framed.displacement() - f
        world = full.positions() - model.scene.rest_positions
        sums += [d @ d, f @ f,
                 np.sum((framed.positions() - full.positions()) ** 2),
                 np.sum((left_out.positions() - full.positions()) ** 2), np.sum(world**2)]
    deformation_error = math.sqrt(sums[0] / sums[1])
    world_error, left_out_error = np.sqrt(sums[2:4] / sums[4])
    print(f'swing: deformation error {deformation_error:.3%}, world error {world_error:.3%}, '
          f'turn left out {left_out_error:.1%}')
    assert deformation_error < 0.02
    assert left_out_error > 50 * world_error


@pytest.mark.slow
def test_cantilever_turning_about_y_stays_within_two_percent():
    scene = variant('cantilever_3d', anchor_motion=[
        {'rotation': 'y', 'amplitude_deg': 30.0, 'frequency_hz': 0.5, 'pivot': [0.0, 0.1, 0.0],
         'ramp_s': 1.0}])
    model = MassSpringModel(scene)
    basis = ModalBasis(model)
    errors = deformation_errors(model, basis, {
        'derivatives': ModalSimulation(model, basis, LOWPASS_0_14,
                                       ModalSettings(dt=2e-4, basis_kind='derivatives')),
        'rest': ModalSimulation(model, basis, LOWPASS_0_14,
                                ModalSettings(dt=2e-4, basis_kind='rest'))}, 4.0, 2e-4)
    print(f"cantilever turning: derivatives {errors['derivatives']:.3%}, "
          f"rest {errors['rest']:.1%}")
    assert errors['derivatives'] < 0.02
    # the turn's centrifugal stretch lies far above the band's rest modes
    assert errors['rest'] > 10 * errors['derivatives']

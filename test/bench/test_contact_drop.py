"""
The contact suite: its scenes, what contact costs, and Newton's contact set as the project's.

Newton's side (skipped where the optional peer is not installed): a particle resting on a plane
sinks by the same ``g dt^2 / c^2`` the project states for its own contact (the same stiffness),
and a sheet lowered onto a sphere never ends a step inside it.
"""
from __future__ import annotations

from helpers import variant
from modal_spring_ros.bench.peers import contact_drop, newton_peer
from modal_spring_ros.core.loads.contact import CONTACT_RATE
from modal_spring_ros.scenes.schema import scene_from_dict
import numpy as np
import pytest

needs_newton = pytest.mark.skipif(not newton_peer.AVAILABLE, reason=newton_peer.MISSING)
G = 9.81


@pytest.mark.parametrize('collider', contact_drop.COLLIDERS)
def test_the_sheet_hangs_its_clearance_above_what_it_is_lowered_onto(collider):
    scene = contact_drop.lowered_sheet(collider)
    (shape,) = scene.contact.colliders
    lowest = scene.rest_positions[~scene.fixed][:, 2].min()
    top = shape.center[2] + shape.radius if collider == 'sphere' else shape.point[2]
    assert lowest - top == pytest.approx(contact_drop.CLEARANCE, abs=1e-9)
    assert scene.contact.sliding_friction == contact_drop.FRICTION
    assert newton_peer.refusal(scene) == ''                # the peer runs it as it is
    lowered = scene.anchor_motion.offset(1.0)
    assert lowered[2] == pytest.approx(-contact_drop.LOWERED, rel=1e-9)


def test_what_contact_costs_is_each_run_over_the_same_run_without_colliders():
    rows = [{'run': 'full', 'cpu_per_s': 0.3},
            {'run': 'full, without colliders', 'cpu_per_s': 0.2},
            {'run': '16 modes + derivatives', 'cpu_per_s': 0.06},
            {'run': '16 modes + derivatives, without colliders', 'cpu_per_s': 0.04},
            {'run': 'auto', 'cpu_per_s': 0.1}]
    assert contact_drop.contact_cost(rows) == pytest.approx(
        {'full': 1.5, '16 modes + derivatives': 1.5})


def test_colliders_the_peer_cannot_place_are_refused_with_the_reason():
    capsule = {'shape': 'capsule', 'a': [0, 0, -1], 'b': [1, 0, -1], 'radius': 0.1}
    sheet = variant('sheet_32x32_resonance', contact={'colliders': [capsule]})
    assert 'capsule colliders' in newton_peer.refusal(sheet)
    attached = variant('sheet_32x32_resonance', contact={'colliders': [
        {'shape': 'sphere', 'center': [0, 0, -2], 'radius': 0.1, 'frame': 'tool0'}]})
    assert 'attached to frames' in newton_peer.refusal(attached)
    assert 'bends' in newton_peer.refusal(variant('cloth_3d'))


def _particle(dt: float):
    """Return a 10 g particle 1 cm over a plane, on a spring too soft to matter."""
    return scene_from_dict({
        'name': 'particle', 'dimension': 3,
        'particles': {'positions': [[0.0, 0.0, 1.0], [0.0, 0.0, 0.01]], 'mass': 0.01},
        'springs': {'pairs': [[0, 1]], 'stiffness': 1e-6}, 'fixed': {'indices': [0]},
        'gravity': [0.0, 0.0, -G], 'reference': 'rest', 'simulation': {'dt': dt},
        'contact': {'friction': 0.4, 'colliders': [
            {'shape': 'plane', 'point': [0, 0, 0], 'normal': [0, 0, 1]}]}})


@needs_newton
def test_newtons_particle_rests_on_a_plane_as_deep_as_the_projects_stated_bound():
    dt = 1e-3
    run = newton_peer.NewtonRun(_particle(dt), dt)
    run.step(3000)                                         # dropped 1 cm, settled
    z = run._state.particle_q.numpy()[1, 2]
    assert -z == pytest.approx(G * dt ** 2 / CONTACT_RATE[1] ** 2, rel=0.05)


@needs_newton
def test_newtons_sheet_lowered_onto_a_sphere_stays_outside_it():
    scene = contact_drop.lowered_sheet('sphere')
    (sphere,) = scene.contact.colliders
    run = newton_peer.NewtonRun(scene, 5e-4)
    deepest = 0.0
    for _ in range(20):
        run.step(100)
        x = run._state.particle_q.numpy().astype(float)
        deepest = max(deepest, float((sphere.radius
                                      - np.linalg.norm(x - sphere.center, axis=1)).max()))
    assert deepest < 1e-3                                  # millimetres at most, never through

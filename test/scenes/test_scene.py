"""Scenes: built-ins as documented, and every invalid case with its message."""
from __future__ import annotations

import copy
import math

from helpers import variant
from modal_spring_ros.core.bases.basis import ModalBasis
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.model.scene import SceneError
from modal_spring_ros.core.simulations import FullSimulation
from modal_spring_ros.scenes.files.writing import scene_to_dict, scene_to_yaml
from modal_spring_ros.scenes.resources import builtin_scene_names, load_scene
from modal_spring_ros.scenes.schema import scene_from_dict, scene_from_yaml
import numpy as np
import pytest


def test_builtin_scenes_are_listed():
    names = builtin_scene_names()
    for expected in ('sheet_10x10', 'chain_2', 'sheet_32x32', 'sheet_100x100', 'cantilever_3d'):
        assert expected in names


def test_sheet_10x10_is_the_papers_scene():
    s = load_scene('sheet_10x10')
    assert s.n_particles == 100
    assert s.dimension == 2
    assert s.fixed.sum() == 10                     # the top row
    assert np.all(s.rest_positions[s.fixed, 2] == s.rest_positions[:, 2].max())
    assert s.n_free_dof == 180                     # paper: 180 vibration systems
    assert s.n_springs == 2 * 9 * 10 + 2 * 9 * 9   # edges + both diagonals per cell
    # hanging in the vertical x-z plane of a z-up world (REP 103)
    assert s.axes == (0, 2) and np.all(s.rest_positions[:, 1] == 0.0)
    assert np.allclose(s.gravity, [0.0, 0.0, -9.81])


@pytest.mark.parametrize('name', builtin_scene_names())
def test_every_built_in_scene_lives_in_a_z_up_world(name):
    s = load_scene(name)
    assert s.gravity[2] < 0.0 and np.all(s.gravity[:2] == 0.0), s.gravity
    if s.dimension == 2:
        assert s.axes == (0, 2)  # hanging in the vertical x-z plane
        # the clamp is the top row, the sheet hangs below it
        assert np.all(s.rest_positions[s.fixed, 2] == s.rest_positions[:, 2].max())


@pytest.mark.parametrize('plane', ['xz', 'xy', 'yz'])
def test_a_2d_sheet_is_a_surface_in_whichever_plane_it_lives_in(plane):
    data = scene_to_dict(load_scene('sheet_10x10'))
    data['plane'] = plane
    data['particles'] = {'lattice': {'counts': [4, 3], 'spacing': 0.1}, 'mass': 0.01}
    data['springs'] = {'connect': ['edges', 'diagonals'], 'stiffness': 1000.0}
    data['fixed'] = {'indices': [0, 1, 2, 3]}
    data.update(gravity=[0.0, 0.0], anchor_motion=[])
    s = scene_from_dict(data)
    tris = s.surface_triangles()
    assert tris.shape == (2 * 3 * 2, 3)        # two per cell, each cell's corners
    area = np.cross(s.rest_positions[tris[:, 1]] - s.rest_positions[tris[:, 0]],
                    s.rest_positions[tris[:, 2]] - s.rest_positions[tris[:, 0]])
    np.testing.assert_allclose(np.linalg.norm(area, axis=1), 0.01)   # none degenerate


def test_a_2d_scene_says_which_plane_it_lives_in():
    data = {'name': 'floor', 'dimension': 2, 'plane': 'xy',
            'particles': {'positions': [[0, 0], [1, 0], [1, 1]], 'mass': 1.0},
            'springs': {'pairs': [[0, 1], [1, 2], [0, 2]], 'stiffness': 10.0},
            'fixed': {'indices': [0]}}
    s = scene_from_dict(data)
    assert s.axes == (0, 1) and s.rest_positions[2].tolist() == [1.0, 1.0, 0.0]
    data['plane'] = 'yz'  # two numbers are in the plane's own coordinates
    s = scene_from_dict(data)
    assert s.axes == (1, 2) and s.rest_positions[2].tolist() == [0.0, 1.0, 1.0]
    del data['plane']  # the default: the vertical x-z plane
    s = scene_from_dict(data)
    assert s.axes == (0, 2) and s.rest_positions[2].tolist() == [1.0, 0.0, 1.0]
    assert scene_from_yaml(scene_to_yaml(s)).axes == (0, 2)  # the plane round-trips


def test_sheet_10x10_stays_in_the_small_deformation_regime():
    """Largest spring strain under gravity below 5 % (the drop from rest included)."""
    scene = variant('sheet_10x10', anchor_motion=[])
    model = MassSpringModel(scene)
    sim = FullSimulation(model, dt=5e-4, basis=ModalBasis(model))
    worst = 0.0
    for _ in range(400):
        sim.step(5)
        worst = max(worst, sim.max_strain())
    assert 0.001 < worst < 0.05


def test_3d_scene_has_out_of_plane_motion():
    s = load_scene('cantilever_3d')
    assert s.dimension == 3 and np.ptp(s.rest_positions[:, 2]) > 0
    model = MassSpringModel(s)
    basis = ModalBasis(model)
    # The square section bends equally in y and z: a degenerate pair of lowest modes.
    assert basis.frequencies_hz[0] == pytest.approx(basis.frequencies_hz[1], rel=1e-8)
    z_share = np.abs(basis.vectors[2::3, :2]).sum()
    assert z_share > 0.1 * np.abs(basis.vectors[:, :2]).sum()


def test_scene_round_trips_through_its_full_definition():
    s = load_scene('sheet_10x10')
    again = scene_from_yaml(scene_to_yaml(s))
    for field in ('rest_positions', 'mass', 'springs', 'stiffness', 'rest_length', 'fixed',
                  'gravity'):
        assert np.array_equal(getattr(s, field), getattr(again, field)), field
    assert again.damping == s.damping and again.anchor_motion == s.anchor_motion


_TURN = {'amplitude_deg': 10, 'frequency_hz': 1, 'pivot': [0.5, 0.0]}


def _chain(**override):
    data = {
        'name': 'bad', 'dimension': 2,
        'particles': {'positions': [[0, 0], [1, 0], [1, 1]], 'mass': 1.0},
        'springs': {'pairs': [[0, 1], [1, 2], [0, 2]], 'stiffness': 10.0},
        'fixed': {'indices': [0]},
    }
    for key, value in override.items():
        section, _, field = key.partition('__')
        if field:
            data[section] = dict(data[section], **{field: value})
        else:
            data[section] = value
    return data


@pytest.mark.parametrize('override, message', [
    ({'particles__mass': -1.0}, 'particles.mass: must be positive, got -1'),
    ({'particles__mass': [1.0, 0.0, 1.0]}, 'particles.mass[1]: must be positive, got 0'),
    ({'springs__stiffness': 0.0}, 'springs.stiffness: must be positive, got 0'),
    ({'springs__stiffness': [1.0, -2.0, 1.0]}, 'springs.stiffness[1]: must be positive'),
    ({'particles__positions': [[0, 0], [1, 0], [1, 0]]},
     'springs.pairs[1]: zero-length spring: particles 1 and 2 are at the same position'),
    ({'springs__pairs': [[0, 1], [1, 2], [1, 0]]},
     'springs.pairs[2]: duplicate spring 0-1 (same as springs.pairs[0])'),
    ({'springs__pairs': [[0, 1], [1, 3], [0, 2]]},
     'springs.pairs[1]: particle index 3 out of range (0..2)'),
    ({'springs__pairs': [[0, 1], [1, 1], [0, 2]]},
     'springs.pairs[1]: connects particle 1 to itself'),
    ({'springs__pairs': [[0, 1]], 'springs__stiffness': 1.0},
     'springs: 1 particle(s) no spring reaches: 2'),
    ({'particles__positions': [[0, 0], [1, 0], [1, 1], [2, 1]],
      'springs__pairs': [[0, 1], [2, 3]], 'springs__stiffness': 10.0},
     "fixed: 1 of the object's 2 parts (particles joined by springs) holds no fixed particle, "
     'so nothing holds it: the largest, 2 particles around (1.5, 0, 1), is particles 2, 3; fix '
     'a particle of each part, or join it to a held one with springs'),
    ({'fixed': {'indices': []}}, 'fixed: no particle is fixed'),
    ({'fixed': None}, 'fixed: missing: at least one particle must be fixed'),
    ({'fixed': {'indices': [7]}}, 'fixed.indices[0]: particle index 7 out of range (0..2)'),
    ({'dimension': 4}, 'dimension: must be 1, 2 or 3, got 4'),
    ({'gravity': [0, -9.81, 0]}, 'gravity: a 2D scene moves along x, z only'),
    ({'particles__positions': [[0, 0, 0], [1, 0, 0], [1, 1, 1]]},
     'particles: a 2D scene must have equal y for every particle'),
    ({'anchor_motion': [{'axis': 'y', 'amplitude': 1, 'frequency_hz': 1}]},
     'anchor_motion[0].axis: must be one of x, z'),
    ({'damping': {'ratio': -0.1}}, 'damping.ratio: must not be negative'),
    ({'colour': 'red'}, 'colour: unknown key'),
    ({'anchor_motion': [{'rotation': 'w', **_TURN}]},
     "anchor_motion[0].rotation: must be one of x, y, z, got 'w'"),
    ({'anchor_motion': [{'rotation': 'x', **_TURN}]},
     'anchor_motion[0].rotation: a turn about x leaves the xz plane of this 2D scene: turn '
     'about y'),
    ({'anchor_motion': [{'rotation': 'y', 'amplitude_deg': 10, 'frequency_hz': 1}]},
     'anchor_motion[0].pivot: missing: the point the axis goes through'),
    ({'anchor_motion': [{'rotation': 'y', **dict(_TURN, pivot=[0, 'a'])}]},
     "anchor_motion[0].pivot[1]: must be a number, got 'a'"),
    ({'anchor_motion': [{'rotation': 'y', **dict(_TURN, amplitude=3)}]},
     'anchor_motion[0].amplitude: unknown key (known keys: rotation, amplitude_deg'),
    ({'anchor_motion': [{'rotation': 'y', 'pivot': [0, 0], 'frequency_hz': 1}]},
     'anchor_motion[0].amplitude_deg: missing'),
    ({'anchor_motion': [{'axis': 'x', 'amplitude': 1, 'frequency_hz': 1, 'pivot': [0, 0]}]},
     'anchor_motion[0].pivot: unknown key (known keys: axis, amplitude'),
])
def test_invalid_scene_names_field_and_problem(override, message):
    with pytest.raises(SceneError) as err:
        scene_from_dict(_chain(**override), source='bad.yaml')
    assert str(err.value).startswith('bad.yaml: ')
    assert message in str(err.value)


def test_a_1d_scene_cannot_turn():
    data = {'name': 'rod', 'dimension': 1, 'axis': 'x',
            'particles': {'positions': [[0, 0], [1, 0]], 'mass': 1.0},
            'springs': {'pairs': [[0, 1]], 'stiffness': 10.0}, 'fixed': {'indices': [0]},
            'anchor_motion': [{'rotation': 'z', **_TURN}]}
    with pytest.raises(SceneError, match=r'anchor_motion\[0\]\.rotation: a 1D scene cannot '
                       'turn'):
        scene_from_dict(data)


def test_a_turning_clamp_round_trips_and_composes_in_order():
    s = load_scene('sheet_10x10_swing')
    (turn,) = s.anchor_motion.rotations
    assert turn.axis == 1 and turn.pivot == (0.45, 0.0, 0.0)
    assert turn.amplitude == pytest.approx(math.radians(45.0), rel=1e-15)
    again = scene_from_yaml(scene_to_yaml(s))
    for t in (0.3, 1.7, 4.1):
        a, b = s.anchor_motion.frame(t), again.anchor_motion.frame(t)
        np.testing.assert_allclose(a.rotation, b.rotation, rtol=0, atol=1e-15)
    # a 3D clamp: a turn about z, then one about x, then the offset
    data = scene_to_dict(load_scene('cantilever_3d'))
    data['anchor_motion'] = [
        {'rotation': 'z', 'amplitude_deg': 90.0, 'frequency_hz': 0.0, 'phase': math.pi / 2,
         'pivot': [0, 0, 0]},
        {'rotation': 'x', 'amplitude_deg': 90.0, 'frequency_hz': 0.0, 'phase': math.pi / 2,
         'pivot': [0, 0, 0]},
        {'axis': 'y', 'amplitude': 2.0, 'frequency_hz': 0.0, 'phase': math.pi / 2}]
    frame = scene_from_dict(data).anchor_motion.frame(0.0)
    # e_x -> (z) e_y -> (x) e_z, then shifted 2 along y
    np.testing.assert_allclose(frame.carry(np.array([[1.0, 0.0, 0.0]])), [[0.0, 2.0, 1.0]],
                               atol=1e-15)


def test_valid_minimal_scene_loads():
    s = scene_from_dict(_chain())
    assert s.n_particles == 3 and s.n_springs == 3


def test_mechanism_reports_zero_mode_count_and_advice():
    # A square of four particles, top two fixed, edge springs only: the bottom edge can sway
    # sideways with no spring stretched: exactly one zero-stiffness mode.
    data = {
        'name': 'mechanism', 'dimension': 2,
        'particles': {'positions': [[0, 0], [1, 0], [0, 1], [1, 1]], 'mass': 1.0},
        'springs': {'pairs': [[0, 1], [0, 2], [1, 3], [2, 3]], 'stiffness': 10.0},
        'fixed': {'indices': [2, 3]},
    }
    with pytest.raises(SceneError, match=r'1 zero-stiffness mode\(s\) \(a mechanism\)') as err:
        ModalBasis(MassSpringModel(scene_from_dict(data)))
    assert 'shear (diagonal) springs' in str(err.value)
    # The same square with one diagonal is rigid.
    data['springs']['pairs'].append([0, 3])
    assert ModalBasis(MassSpringModel(scene_from_dict(data))).count == 4


def test_sheet_without_diagonals_is_a_mechanism_on_the_sparse_path_too():
    data = copy.deepcopy(scene_to_dict(load_scene('sheet_32x32')))
    keep = [p for p in data['springs']['pairs']
            if abs(data['particles']['positions'][p[0]][0]
                   - data['particles']['positions'][p[1]][0]) < 1e-12
            or abs(data['particles']['positions'][p[0]][2]
                   - data['particles']['positions'][p[1]][2]) < 1e-12]
    data['springs'] = {'pairs': keep, 'stiffness': 1000.0}
    model = MassSpringModel(scene_from_dict(data))
    with pytest.raises(SceneError, match='zero-stiffness mode'):
        ModalBasis(model)


def test_unknown_scene_and_unreadable_file(tmp_path):
    with pytest.raises(SceneError, match="unknown scene 'nope'.*built-in: .*sheet_10x10"):
        load_scene('nope')
    with pytest.raises(SceneError, match='cannot read scene file'):
        load_scene(tmp_path / 'missing.yaml')
    bad = tmp_path / 'bad.yaml'
    bad.write_text('particles: [1, 2\n')
    with pytest.raises(SceneError, match='invalid YAML'):
        load_scene(bad)


@pytest.mark.parametrize('t', [0.0, 0.3, 0.9999, 1.0, 1.7, 4.2])
def test_anchor_velocity_and_acceleration_are_the_derivatives_of_its_offset(t):
    """Within the ramp (1 s on sheet_10x10), at its end and after it."""
    motion = load_scene('sheet_10x10').anchor_motion
    assert len(motion.components) == 2 and all(c.ramp_s == 1.0 for c in motion.components)
    h = 1e-5
    before, after = (t - h, t + h) if t >= h else (t, t + 2 * h)  # no motion before t = 0
    velocity = (motion.offset(after) - motion.offset(before)) / (after - before)
    accel = (motion.velocity(after) - motion.velocity(before)) / (after - before)
    mid = 0.5 * (before + after)
    scale = np.abs(motion.acceleration(mid)).max() + 1e-3
    np.testing.assert_allclose(velocity, motion.velocity(mid), atol=1e-6 * scale, rtol=1e-5)
    np.testing.assert_allclose(accel, motion.acceleration(mid), atol=1e-4 * scale, rtol=1e-4)
    assert motion.offset(0.0).tolist() == [0.0, 0.0, 0.0]


def test_a_ramped_motion_starts_and_ends_its_ramp_without_a_step_in_the_load():
    """
    Base velocity and acceleration (the load) are continuous at both ends of the ramp.

    Even for a phase that starts the sine away from zero.
    """
    from modal_spring_ros.core.motion.anchor_motion import AnchorMotion, SineComponent
    motion = AnchorMotion((SineComponent(axis=0, amplitude=0.02, frequency_hz=0.7, phase=1.0,
                                         ramp_s=0.5),))
    for order in ('offset', 'velocity', 'acceleration'):
        assert getattr(motion, order)(0.0).tolist() == [0.0, 0.0, 0.0]
        at_end = getattr(motion, order)
        steady = np.abs(at_end(0.5 + 1e-9)).max()
        assert steady > 1e-3
        np.testing.assert_allclose(at_end(0.5 - 1e-9), at_end(0.5 + 1e-9), rtol=1e-6)


@pytest.mark.parametrize('ramp_s', [1e-300, 5e-324])
def test_a_ramp_too_short_to_square_is_a_motion_without_a_ramp(ramp_s):
    """A scene's ramp of 1e-300 s (its square underflows) built and stepped: no division by 0."""
    data = scene_to_dict(load_scene('sheet_10x10_resonance'))
    runs = []
    for ramp in (ramp_s, 0.0):
        data['anchor_motion'][0]['ramp_s'] = ramp
        scene = scene_from_dict(copy.deepcopy(data))
        assert scene.anchor_motion.acceleration(0.0).tolist() == [0.0, 0.0, 0.0]
        model = MassSpringModel(scene)
        runs.append(FullSimulation(model, dt=5e-4, basis=ModalBasis(model)))
        runs[-1].step(20)
    np.testing.assert_array_equal(runs[0].displacement(), runs[1].displacement())
    assert np.abs(runs[0].displacement()).max() > 0.0

"""The published cloud's layout and values, and the particle positions it is built from."""
from __future__ import annotations

from modal_spring_ros.bags.messages.pointcloud import (CloudBuffer, distance_from_rest,
                                                       from_pointcloud2, to_pointcloud2, xyz)
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.scenes.files.writing import scene_to_dict
from modal_spring_ros.scenes.resources import load_scene
from modal_spring_ros.scenes.schema import scene_from_dict
import numpy as np
import pytest
from std_msgs.msg import Header


def test_cloud_layout_and_values_round_trip():
    rng = np.random.default_rng(3)
    rest = rng.normal(size=(50, 3))
    positions = rest + rng.normal(scale=0.01, size=(50, 3))
    msg = to_pointcloud2(positions, rest, Header(frame_id='world'))
    assert (msg.height, msg.width, msg.point_step, msg.row_step) == (1, 50, 16, 800)
    assert [(f.name, f.offset, f.datatype, f.count) for f in msg.fields] == [
        ('x', 0, 7, 1), ('y', 4, 7, 1), ('z', 8, 7, 1), ('displacement', 12, 7, 1)]
    assert msg.is_dense and not msg.is_bigendian and len(msg.data) == 800
    cloud = from_pointcloud2(msg)
    np.testing.assert_array_equal(xyz(msg), positions.astype(np.float32).astype(np.float64))
    expected = np.array([np.sqrt(sum((p - r) ** 2)) for p, r in zip(positions, rest)])
    # from the float32 positions the cloud carries: to their resolution
    np.testing.assert_allclose(cloud['displacement'], expected, rtol=1e-6,
                               atol=4e-7 * np.abs(positions).max())


def test_a_cloud_buffer_is_written_in_place_frame_after_frame():
    rng = np.random.default_rng(4)
    rest = rng.normal(size=(40, 3))
    cloud = CloudBuffer(rest)
    first = rest + 0.01
    cloud.write(first)
    assert cloud.finite()
    msg = cloud.message(Header(frame_id='world'))
    np.testing.assert_allclose(xyz(msg), first, atol=1e-6)
    np.testing.assert_allclose(from_pointcloud2(msg)['displacement'], np.sqrt(3) * 0.01,
                               rtol=1e-4)
    cloud.write(rest)  # the next frame: the same bytes, no new array
    again = cloud.message(Header(frame_id='world'))
    assert again.data is msg.data and np.all(from_pointcloud2(again)['displacement'] < 1e-6)
    movement = rng.normal(scale=0.1, size=(3, 40))  # a frame from each particle's movement
    cloud.movement[...] = movement
    cloud.write_movement()
    assert cloud.finite()
    np.testing.assert_allclose(xyz(msg), rest + movement.T, rtol=0, atol=1e-6)
    np.testing.assert_allclose(from_pointcloud2(msg)['displacement'],
                               np.linalg.norm(movement, axis=0), rtol=1e-6)
    for bad in (np.nan, np.inf, 1e30):  # 1e30: off float32's range once squared
        positions = rest.copy()
        positions[7, 1] = bad
        cloud.write(positions)
        assert not cloud.finite()
        cloud.movement[1, 7] = bad
        cloud.write_movement()
        assert not cloud.finite()
        cloud.write(rest)
        assert cloud.finite()


def test_distance_from_rest_is_the_euclidean_distance():
    rest = np.zeros((3, 3))
    positions = np.array([[3.0, 4.0, 0.0], [0.0, 0.0, -2.0], [1.0, 2.0, 2.0]])
    np.testing.assert_allclose(distance_from_rest(positions, rest), [5.0, 2.0, 3.0],
                               rtol=1e-15)


@pytest.mark.parametrize('change, message', [
    (lambda m: m.fields.reverse(), 'unexpected PointCloud2 layout'),
    (lambda m: setattr(m, 'is_bigendian', True), 'big-endian'),
])
def test_other_layouts_are_refused_by_name(change, message):
    msg = to_pointcloud2(np.ones((2, 3)), np.zeros((2, 3)), Header())
    msg.fields = list(msg.fields)
    change(msg)
    with pytest.raises(ValueError, match=message):
        from_pointcloud2(msg)


def test_positions_put_each_free_particle_at_rest_plus_base_plus_displacement():
    model = MassSpringModel(load_scene('sheet_10x10'))
    d = model.dimension
    u = np.arange(model.n_free_dof, dtype=float) * 1e-4
    t = 0.37
    x = model.positions(u, t)
    offset = model.anchor_offset(t)
    assert np.abs(offset).max() > 0.0                          # the anchors do move at t
    np.testing.assert_array_equal(x[model.fixed_particles],
                                  model.rest[model.fixed_particles] + offset)
    np.testing.assert_allclose(x[model.free_particles],
                               model.rest[model.free_particles] + offset + u.reshape(-1, d),
                               rtol=0, atol=1e-15)


def sheet_in_the_xy_plane():
    """Return a small 2D sheet whose axes are x and y (rows next to each other in a frame)."""
    data = scene_to_dict(load_scene('sheet_10x10'))
    data.update(name='sheet_xy', plane='xy', gravity=[0.0, -9.81],
                particles={'lattice': {'counts': [6, 5], 'spacing': 0.1}, 'mass': 0.01},
                springs={'connect': ['edges', 'diagonals'], 'stiffness': 1000.0},
                fixed={'indices': list(range(6))},
                anchor_motion=[{'axis': 'y', 'amplitude': 0.01, 'frequency_hz': 2.0}])
    return scene_from_dict(data)


# a 2D scene in x-z with moving clamps, one turning, a 3D one, a 2D one in x-y
@pytest.mark.parametrize('scene', ['sheet_10x10', 'sheet_10x10_swing', 'cantilever_3d', 'xy'])
def test_frames_written_in_place_are_the_run_s_positions_in_float32(scene):
    scene = sheet_in_the_xy_plane() if scene == 'xy' else load_scene(scene)
    sim = build_simulation(scene, SimulationConfig())
    sim.step(300)
    sim.set_band(FilterBand('lowpass', 0, 5, 'index'), 0.5)  # the frames of a fade, too
    sim.step(100)
    cloud = CloudBuffer(sim.model.scene.rest_positions)
    for _ in range(2):  # the second frame writes over the first
        sim.step(50)
        cloud.write_run(sim)
        reference = sim.positions()
        assert np.abs(reference - reference[0]).max() > 1e-3
        np.testing.assert_allclose(cloud.points[:, :3], reference, rtol=0,
                                   atol=3e-7 * np.abs(reference).max())
        distance = distance_from_rest(reference, scene.rest_positions)
        assert distance.max() > 1e-4
        np.testing.assert_allclose(cloud.points[:, 3], distance, rtol=0,
                                   atol=1e-6 * distance.max())

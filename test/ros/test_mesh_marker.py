"""What RViz draws of each scene: its surface's triangles, or its springs where it has none."""
from __future__ import annotations

from modal_spring_ros.ros.markers.mesh_marker import marker_cells, mesh_marker
from modal_spring_ros.scenes.resources import builtin_scene_names, load_scene
import numpy as np
import pytest
from std_msgs.msg import Header
from visualization_msgs.msg import Marker


@pytest.mark.parametrize('name', builtin_scene_names())
def test_every_built_in_scene_draws_something_that_covers_every_particle_it_shows(name):
    if name == 'sheet_316x316':
        pytest.skip('100k particles: the same lattice as sheet_32x32')
    scene = load_scene(name)
    cells, width = marker_cells(scene)
    assert cells.size and cells.min() >= 0 and cells.max() < scene.n_particles
    marker = mesh_marker(scene.rest_positions + 0.01, scene.rest_positions, cells, Header(),
                         width)
    if name in ('chain_2', 'cable_3d'):                  # a chain and a cable: no surface
        assert marker.type == Marker.LINE_LIST and marker.scale.x == width > 0.0
        assert len(marker.points) == 2 * scene.n_springs
    else:
        assert marker.type == Marker.TRIANGLE_LIST and len(marker.points) == cells.size
    assert len(marker.colors) == len(marker.points)


def test_a_lattice_block_shows_its_skin_turned_outward():
    scene = load_scene('cantilever_3d')                  # 12 x 3 x 3 particles
    skin = scene.surface_triangles()
    assert skin.shape == (2 * (2 * 2 * 2 + 2 * 11 * 2 + 2 * 11 * 2), 3)
    x = scene.rest_positions
    a, b, c = x[skin[:, 0]], x[skin[:, 1]], x[skin[:, 2]]
    # divergence theorem: outward triangles enclose the block's volume with a plus sign
    enclosed = np.einsum('ij,ij->i', a, np.cross(b, c)).sum() / 6.0
    assert enclosed == pytest.approx(np.prod(x.max(axis=0) - x.min(axis=0)), rel=1e-12)
    inner = np.all((x > x.min(axis=0) + 1e-9) & (x < x.max(axis=0) - 1e-9), axis=1)
    assert not np.isin(np.flatnonzero(inner), skin).any()        # only the skin is drawn

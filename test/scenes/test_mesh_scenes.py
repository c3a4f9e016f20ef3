"""Meshes are scenes: surfaces and volumes read from files, their springs, masses and refusals."""
from __future__ import annotations

from pathlib import Path

from modal_spring_ros.core.bases.basis import ModalBasis
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.model.scene import SceneError
from modal_spring_ros.scenes.inside import inside_closed_surface
from modal_spring_ros.scenes.resources import load_scene
from modal_spring_ros.scenes.schema import scene_from_dict
from modal_spring_ros.scenes.writing import scene_to_dict
import numpy as np
import pytest
from scipy.spatial import Delaunay


def write_obj(path: Path, vertices, faces) -> Path:
    lines = [f'v {x:.9f} {y:.9f} {z:.9f}' for x, y, z in vertices]
    lines += [f'f {a + 1} {b + 1} {c + 1}' for a, b, c in faces]
    path.write_text('\n'.join(lines) + '\n')
    return path


def cloth_mesh(count: int, size: float = 0.5, jitter: float = 0.25, seed: int = 1):
    """Return a square cloth in the x-z plane (top edge at z = 0), irregularly triangulated."""
    h = size / (count - 1)
    u, v = np.meshgrid(np.arange(count) * h, np.arange(count) * h)
    p = np.column_stack([u.ravel(), v.ravel()])
    inner = np.all((p > 1e-9) & (p < size - 1e-9), axis=1)
    p[inner] += np.random.default_rng(seed).uniform(-jitter, jitter, (inner.sum(), 2)) * h
    faces = Delaunay(p).simplices
    return np.column_stack([p[:, 0], np.zeros(len(p)), p[:, 1] - size]), faces


def cloth_scene(path: Path, **changes) -> dict:
    scene = {'dimension': 3, 'mesh': {'file': str(path), 'kind': 'surface'},
             'material': {'density': 0.2, 'stiffness': 400.0, 'bending': 0.05},
             'fixed': {'box': {'min': [-1, -1, -0.001], 'max': [1, 1, 0.001]}},
             'gravity': [0.0, 0.0, -9.81]}
    scene.update(changes)
    return scene


def test_a_surface_has_edge_and_bending_springs_masses_from_areas(tmp_path):
    # two right triangles sharing the diagonal 0-2 of a unit square: 5 edges, 1 hinge (1-3)
    square = [(0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1)]
    path = write_obj(tmp_path / 'square.obj', square, [(0, 1, 2), (0, 2, 3)])
    material = {'density': 2.0, 'stiffness': 10.0, 'bending': 0.5}
    scene = scene_from_dict(cloth_scene(path, material=material,
                                        fixed={'indices': [0, 1]}, gravity=[0, 0, 0],
                                        reference='rest'))
    pairs = {tuple(p): k for p, k in zip(scene.springs.tolist(), scene.stiffness)}
    assert set(pairs) == {(0, 1), (1, 2), (2, 3), (0, 3), (0, 2), (1, 3)}
    assert pairs[0, 1] == pytest.approx(10.0 * 0.5 / 1.0)             # k * area / L^2
    assert pairs[0, 2] == pytest.approx(10.0 * 1.0 / 2.0)             # on both triangles
    assert pairs[1, 3] == pytest.approx(0.5 * 10.0 * 1.0 / 2.0)       # bending * k * A / L^2
    assert scene.mass.sum() == pytest.approx(2.0 * 1.0)               # density * area
    assert scene.mass[0] == pytest.approx(2.0 * (0.5 + 0.5) / 3.0)    # on both triangles
    np.testing.assert_array_equal(scene.surface_triangles(), [[0, 1, 2], [0, 2, 3]])


def test_a_mesh_scene_is_written_and_read_back_the_same(tmp_path):
    vertices, faces = cloth_mesh(6)
    scene = scene_from_dict(cloth_scene(write_obj(tmp_path / 'c.obj', vertices, faces)))
    assert scene.loaded
    again = scene_from_dict(scene_to_dict(scene))
    assert again.loaded
    np.testing.assert_allclose(again.rest_positions, scene.rest_positions, atol=1e-12)
    np.testing.assert_array_equal(again.triangles, scene.triangles)
    np.testing.assert_allclose(again.stiffness, scene.stiffness)


def test_scale_rotation_and_translation_place_the_mesh(tmp_path):
    path = write_obj(tmp_path / 't.obj', [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1, 2)])
    (tmp_path / 'scene.yaml').write_text('')  # the mesh file is named relative to it
    scene = scene_from_dict({
        'dimension': 3, 'reference': 'rest',
        'mesh': {'file': path.name, 'scale': 2.0, 'rotation_deg': [0, 0, 90],
                 'translation': [0, 0, 1]},
        'material': {'density': 1.0, 'stiffness': 1.0}, 'fixed': {'indices': [0]}},
        source=str(tmp_path / 'scene.yaml'), default_name='t')
    np.testing.assert_allclose(scene.rest_positions, [(0, 0, 1), (0, 2, 1), (-2, 0, 1)],
                               atol=1e-12)


@pytest.mark.parametrize('make, problem', [
    (lambda d: d / 'missing.obj', 'cannot read mesh file'),
    (lambda d: d / 'mesh.xyz', 'unknown mesh format'),
    (lambda d: write_obj(d / 'none.obj', [(0, 0, 0), (1, 0, 0), (0, 1, 0)], []),
     'no triangles'),
    (lambda d: write_obj(d / 'flat.obj', [(0, 0, 0), (1, 0, 0), (2, 0, 0), (0, 1, 0)],
                         [(0, 1, 2), (0, 1, 3)]), 'triangle 0 is degenerate'),
    (lambda d: write_obj(d / 'twice.obj', [(0, 0, 0), (1, 0, 0), (0, 1, 0)],
                         [(0, 1, 2), (1, 2, 0)]), 'listed more than once'),
])
def test_bad_meshes_are_refused_in_one_line_naming_the_problem(tmp_path, make, problem):
    with pytest.raises(SceneError, match=problem) as error:
        scene_from_dict(cloth_scene(make(tmp_path), fixed={'indices': [0]}))
    assert '\n' not in str(error.value) and 'mesh' in str(error.value)


def test_a_volume_needs_a_closed_surface_and_a_region_must_hold_a_particle(tmp_path):
    vertices, faces = cloth_mesh(4)
    path = write_obj(tmp_path / 'open.obj', vertices, faces)
    with pytest.raises(SceneError, match='needs a closed surface.*holes'):
        scene_from_dict(cloth_scene(path, mesh={'file': str(path), 'kind': 'volume'}))
    with pytest.raises(SceneError, match='fixed.near: holds no particle'):
        scene_from_dict(cloth_scene(path, fixed={'near': {'point': [5, 5, 5],
                                                          'radius': 0.1}}))
    with pytest.raises(SceneError, match="package 'no_such_package'"):
        scene_from_dict(cloth_scene('package://no_such_package/cloth.obj'))


def test_a_closed_surface_is_filled_with_tetrahedra_that_keep_its_skin_and_volume(tmp_path):
    trimesh = pytest.importorskip('trimesh')
    box = trimesh.creation.box(extents=[1.0, 0.2, 0.2]).subdivide().subdivide()
    box.apply_translation([0.5, 0.0, 0.0])
    path = tmp_path / 'beam.stl'
    box.export(str(path))
    scene = scene_from_dict({
        'dimension': 3, 'mesh': {'file': str(path), 'kind': 'volume'},
        'material': {'density': 1000.0, 'stiffness': 1e5},
        'fixed': {'box': {'min': [-0.01, -1, -1], 'max': [0.01, 1, 1]}},
        'gravity': [0.0, 0.0, -9.81]})
    assert not scene.loaded                        # a solid is stiff at rest
    assert scene.mass.sum() == pytest.approx(1000.0 * 0.04, rel=1e-6)   # STL: float32
    assert scene.n_particles > len(box.vertices)   # the skin's vertices and the inside
    skin = scene.surface_triangles()
    assert skin.shape == (len(box.faces), 3) and skin.max() < len(box.vertices)
    basis = ModalBasis(MassSpringModel(scene))
    basis.ensure_count(4)
    assert basis.frequencies_hz[0] > 0.0


def test_the_inside_of_a_closed_surface_is_found_by_ray_parity():
    trimesh = pytest.importorskip('trimesh')
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    points = np.random.default_rng(3).uniform(-1.2, 1.2, (4000, 3))
    radius = np.linalg.norm(points, axis=1)
    clear = np.abs(radius - 1.0) > 0.02                        # away from the faceted skin
    inside = inside_closed_surface(points, np.asarray(sphere.vertices),
                                   np.asarray(sphere.faces))
    np.testing.assert_array_equal(inside[clear], radius[clear] < 1.0)


def test_the_built_in_cloth_shows_its_own_triangles():
    scene = load_scene('cloth_3d')
    assert scene.loaded and scene.n_particles == 400
    assert scene.surface_triangles().shape == (722, 3)
    assert scene.fixed.sum() == 2


def test_a_finer_mesh_of_a_solid_has_nearly_the_same_low_frequencies(tmp_path):
    """
    The soft block's object (12 x 8 x 8 cm, 1000 kg/m^3, 100 kPa, glued at its base) meshed twice.

    Edges of at most 2 cm and of at most 1.2 cm on the skin (516 and 1908 particles once
    filled): the lowest five frequencies agree within 5 % (measured 1.2-4.9 %, the most in the
    fourth, a torsion: a spring network has no Poisson coupling of its own, so its modes converge
    more slowly than a finite-element solid's; a 4 cm mesh, 133 particles, is up to 15 % off
    there). The lowest, the bending the clamp drives most, within 3 %.
    """
    trimesh = pytest.importorskip('trimesh')
    box = trimesh.creation.box(extents=[0.12, 0.08, 0.08])
    box.apply_translation([0.0, 0.0, 0.04])
    frequencies = []
    for edge in (0.02, 0.012):
        vertices, faces = trimesh.remesh.subdivide_to_size(box.vertices, box.faces,
                                                           max_edge=edge)
        path = write_obj(tmp_path / f'block_{edge}.obj', vertices, faces)
        scene = scene_from_dict({
            'dimension': 3, 'mesh': {'file': str(path), 'kind': 'volume'},
            'material': {'density': 1000.0, 'stiffness': 1e5},
            'fixed': {'box': {'min': [-1, -1, -0.001], 'max': [1, 1, 0.001]}},
            'gravity': [0.0, 0.0, -9.81]})
        basis = ModalBasis(MassSpringModel(scene))
        basis.ensure_count(5)
        frequencies.append(np.asarray(basis.frequencies_hz[:5]))
    coarse, fine = frequencies
    assert np.max(np.abs(coarse / fine - 1.0)) < 0.05, (coarse, fine)
    assert abs(coarse[0] / fine[0] - 1.0) < 0.03, (coarse, fine)

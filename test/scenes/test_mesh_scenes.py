"""Meshes are scenes: surfaces and volumes read from files, their springs, masses and refusals."""
from __future__ import annotations

from pathlib import Path

from helpers import cloth_mesh, write_obj
from modal_spring_ros.core.bases.basis import ModalBasis
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.model.scene import SceneError
from modal_spring_ros.scenes.files.writing import scene_to_dict
from modal_spring_ros.scenes.meshes.inside import inside_closed_surface
from modal_spring_ros.scenes.resources import load_scene
from modal_spring_ros.scenes.schema import scene_from_dict
import numpy as np
import pytest


def cloth_scene(path: Path, **changes) -> dict:
    scene = {'dimension': 3, 'mesh': {'file': str(path), 'kind': 'surface'},
             'material': {'density': 0.2, 'stiffness': 400.0, 'bending': 1e-4},
             'fixed': {'box': {'min': [-1, -1, -0.001], 'max': [1, 1, 0.001]}},
             'gravity': [0.0, 0.0, -9.81]}
    scene.update(changes)
    return scene


def test_a_flat_surface_has_edge_springs_masses_from_areas_and_quadratic_bending(tmp_path):
    # two right triangles sharing the diagonal 0-2 of a unit square: 5 edges, 1 hinge (1-3)
    square = [(0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1)]
    path = write_obj(tmp_path / 'square.obj', square, [(0, 1, 2), (0, 2, 3)])
    material = {'density': 2.0, 'stiffness': 10.0, 'bending': 0.5}
    scene = scene_from_dict(cloth_scene(path, material=material,
                                        fixed={'indices': [0, 1]}, gravity=[0, 0, 0],
                                        reference='rest'))
    pairs = {tuple(p): k for p, k in zip(scene.springs.tolist(), scene.stiffness)}
    assert set(pairs) == {(0, 1), (1, 2), (2, 3), (0, 3), (0, 2)}     # no spring across
    assert pairs[0, 1] == pytest.approx(10.0 * 0.5 / 1.0)             # k * area / L^2
    assert pairs[0, 2] == pytest.approx(10.0 * 1.0 / 2.0)             # on both triangles
    assert scene.mass.sum() == pytest.approx(2.0 * 1.0)               # density * area
    assert scene.mass[0] == pytest.approx(2.0 * (0.5 + 0.5) / 3.0)    # on both triangles
    np.testing.assert_array_equal(scene.surface_triangles(), [[0, 1, 2], [0, 2, 3]])
    # the hinge across 0-2: weights (1, 1, -1, -1) vanish on the square; scaled so that a fold
    # of theta gives |w . x| = theta for small theta, times sqrt(c), c = 3 D |e|^2 / (A1 + A2)
    hinge = scene.bending.hinges[0]
    assert list(hinge[:2]) == [0, 2] and set(hinge[2:]) == {1, 3}
    c = 3.0 * 0.5 * 2.0 / 1.0
    w = dict(zip(hinge.tolist(), scene.bending.weights[0] * np.sign(scene.bending.weights[0, 2])))
    np.testing.assert_allclose([w[0], w[2], w[1], w[3]],
                               np.sqrt(c) * np.sqrt(2.0) * np.array([-1, -1, 1, 1]))
    # folding corner 1 by theta about the diagonal costs 1/2 c |2 sin(theta / 2)|^2, exactly
    model = MassSpringModel(scene)
    for theta in (1e-3, 0.3, 2.0):
        axis = np.array([1.0, 0.0, 1.0]) / np.sqrt(2.0)
        arm = np.array([1.0, 0.0, 0.0]) - 0.5 * np.array([1.0, 0.0, 1.0])  # from the edge
        turned = (np.cos(theta) * arm + np.sin(theta) * np.cross(axis, arm)
                  + 0.5 * np.array([1.0, 0.0, 1.0]))
        x = np.array(square, dtype=float)
        x[1] = turned
        energy = model.energy(x, np.zeros(model.n_free_dof))
        assert energy['spring'] == pytest.approx(0.5 * c * (2.0 * np.sin(theta / 2)) ** 2,
                                                 rel=1e-9)


def test_a_curved_surface_bends_by_springs_across_its_hinges(tmp_path):
    # the same two triangles, corner 3 lifted out of the plane: a curved hinge
    bent = [(0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0.5, 1)]
    path = write_obj(tmp_path / 'bent.obj', bent, [(0, 1, 2), (0, 2, 3)])
    material = {'density': 2.0, 'stiffness': 10.0, 'bending': 0.5}
    scene = scene_from_dict(cloth_scene(path, material=material, fixed={'indices': [0, 1]},
                                        gravity=[0, 0, 0], reference='rest'))
    assert scene.bending is None
    pairs = {tuple(p): k for p, k in zip(scene.springs.tolist(), scene.stiffness)}
    x = np.array(bent)
    areas = [0.5, 0.5 * np.linalg.norm(np.cross(x[2] - x[0], x[3] - x[0]))]
    fold = 3.0 * 0.5 * 2.0 / sum(areas)                               # 3 D |e|^2 / (A1 + A2)
    assert pairs[1, 3] == pytest.approx(fold / np.sum((x[3] - x[1]) ** 2))


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


def test_a_finer_mesh_of_a_hanging_cloth_has_nearly_the_same_low_frequencies(tmp_path):
    """
    A 0.5 m cloth hanging from its top edge, irregularly meshed with 400 and 900 vertices.

    Its modes are taken about the shape it hangs in, and its bending is the quadratic model's:
    the lowest five frequencies agree within 5 % (measured 0.1-3.2 %, 0.85-2.0 Hz). Without
    bending (what springs across flat hinges amount to: they resist a fold only at fourth order)
    the lowest is 0.59, 0.61 and 0.57 Hz at 144, 400 and 900 vertices, set by the mesh.
    """
    frequencies = []
    for count in (20, 30):
        vertices, faces = cloth_mesh(count)
        scene = scene_from_dict(cloth_scene(write_obj(tmp_path / f'c{count}.obj', vertices,
                                                      faces)))
        assert scene.loaded and scene.bending.count > 2 * len(vertices)
        basis = ModalBasis(MassSpringModel(scene))
        basis.ensure_count(5)
        frequencies.append(np.asarray(basis.frequencies_hz[:5]))
    coarse, fine = frequencies
    assert np.max(np.abs(coarse / fine - 1.0)) < 0.05, (coarse, fine)
    assert 0.5 < fine[0] < 1.5   # a hanging chain of 0.5 m sways at 0.85 Hz


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

"""The mesh benchmark: its objects are valid meshes, and a small run measures every figure."""
from __future__ import annotations

import math

from modal_spring_ros.bench.costs import meshes
from modal_spring_ros.core.model.bending import is_flat
from modal_spring_ros.scenes.schema import scene_from_yaml
import numpy as np
import pytest


def test_the_solid_is_a_closed_outward_surface_of_its_vertex_count():
    points, faces = meshes.ellipsoid_mesh(300)
    assert points.shape == (300, 3)
    corners = points[faces]
    signed = np.einsum('ij,ij->i', corners[:, 0], np.cross(corners[:, 1], corners[:, 2])) / 6.0
    # outward: the signed volume is the ellipsoid's (4/3 pi abc), a little less as a polyhedron
    assert 0.95 * 4.0 / 3.0 * math.pi * 0.06 * 0.04 * 0.04 < signed.sum() \
        < 4.0 / 3.0 * math.pi * 0.06 * 0.04 * 0.04
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), 1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert np.all(counts == 2)                      # closed and manifold


def test_the_cloth_is_flat_irregular_and_hangs_from_its_top_edge(tmp_path):
    vertices, faces = meshes.cloth_mesh(12)
    assert vertices.shape == (144, 3) and is_flat(vertices)
    assert np.isclose(vertices[:, 2].max(), 1.0) and np.isclose(vertices[:, 2].min(), 0.5)
    meshes.write_obj(tmp_path / 'cloth.obj', vertices, faces)
    scene_file = tmp_path / 'cloth.yaml'
    scene_file.write_text(meshes.scene_text('cloth', 'cloth.obj'))
    scene = scene_from_yaml(scene_file.read_text(), str(scene_file))
    assert scene.loaded and scene.bending.count > 0
    assert scene.fixed.sum() == 12                   # the top edge


@pytest.mark.slow
def test_a_small_run_measures_load_precompute_steps_and_frames(monkeypatch):
    monkeypatch.setattr(meshes, 'QUICK_CASES', [('cloth', 'cloth', 8), ('solid', 'solid', 120)])
    heard = []
    results = meshes.run(True, heard.append)
    assert [r['kind'] for r in results] == ['cloth', 'solid']
    assert any('loaded shape found' in line for line in heard)      # the stages' progress
    assert sum('modes' in line for line in heard) == 2, heard
    for r in results:
        assert r['ready_s'] == r['load_s'] + r['precompute_s'] > 0.0
        assert r['modal_step_us'] > 0.0 and r['full_step_us'] > 0.0
        assert r['modal_dt'] > r['full_dt']          # the band's modes step longer
        assert math.isclose(r['saving'], r['full_cpu_per_sim_s'] / r['modal_cpu_per_sim_s'])
        assert r['frame_total_us'] > 0.0 and r['peak_mb'] > 0.0
    assert results[1]['particles'] > 120              # the skin, filled
    table = meshes.table(results)
    assert 'cloth' in table and 'goal 20 s' in table

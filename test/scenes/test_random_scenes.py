"""
Random scenes: the same seed gives the same scene, and the demanding ones are what they say.

``demanding_scene`` must bring what the promise is checked on beyond small lattices: solids and
shells read from mesh files, sheets of 5,000 particles and more, clamps turning +-90 degrees,
runs of 20-40 s.
"""
from __future__ import annotations

import math

from modal_spring_ros.scenes.generator import (DEMANDING_DURATION_S, demanding_scene,
                                               LARGE_SHEET_PARTICLES, random_scene)
import numpy as np
import pytest

SEEDS = range(8)


@pytest.fixture(scope='module')
def demanding(tmp_path_factory):
    folder = tmp_path_factory.mktemp('demanding')
    return {seed: demanding_scene(seed, folder) for seed in SEEDS}, folder


def test_the_same_seed_gives_the_same_scene_and_the_same_mesh_file(demanding, tmp_path):
    scenes, folder = demanding
    for seed in (0, 1, 2):
        again = demanding_scene(seed, tmp_path)
        np.testing.assert_array_equal(again.rest_positions, scenes[seed].rest_positions)
        np.testing.assert_array_equal(again.springs, scenes[seed].springs)
        assert again.anchor_motion == scenes[seed].anchor_motion
        written = folder / f'demanding_{seed}.obj'
        if written.exists():
            assert (tmp_path / written.name).read_bytes() == written.read_bytes()
    first = random_scene(5)
    np.testing.assert_array_equal(random_scene(5).rest_positions, first.rest_positions)


def test_the_demanding_scenes_bring_meshes_large_sheets_big_turns_and_long_runs(demanding):
    scenes, folder = demanding
    kinds = {seed: s.description.rsplit(': ', 1)[-1] for seed, s in scenes.items()}
    assert set(kinds.values()) == {'volume', 'flat shell', 'curved shell', 'large sheet'}
    for seed, scene in scenes.items():
        low, high = DEMANDING_DURATION_S
        assert low <= scene.default_duration <= high
        assert np.all(np.isfinite(scene.rest_positions)) and scene.fixed.any()
        if kinds[seed] == 'large sheet':
            assert scene.n_particles >= LARGE_SHEET_PARTICLES[0] and scene.dimension == 2
        else:   # read from the mesh file it wrote
            assert (folder / f'demanding_{seed}.obj').stat().st_size > 1000
            assert scene.dimension == 3 and scene.triangles is not None
        for turn in scene.anchor_motion.rotations:   # a quarter turn each way
            assert turn.amplitude == pytest.approx(math.pi / 2)
    assert sum(bool(s.anchor_motion.rotations) for s in scenes.values()) >= 2

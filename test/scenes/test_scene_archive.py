"""A scene as an archive of arrays (bags and runs keep theirs so): exact, bounded, checked."""
from __future__ import annotations

import io
import zipfile

from modal_spring_ros.core.model.scene import SceneError
from modal_spring_ros.scenes.files import scene_archive
from modal_spring_ros.scenes.files.scene_archive import scene_from_archive, scene_to_archive
from modal_spring_ros.scenes.files.writing import scene_header, scene_to_yaml
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest


def entries(scene_name: str = 'sheet_10x10') -> dict[str, np.ndarray]:
    with np.load(io.BytesIO(scene_to_archive(load_scene(scene_name)))) as npz:
        return {name: npz[name] for name in npz.files}


def archive(arrays: dict[str, np.ndarray]) -> bytes:
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return buffer.getvalue()


@pytest.mark.parametrize('name', ['sheet_10x10', 'soft_block_3d', 'cable_3d', 'chain_2'])
def test_a_scene_comes_back_exactly(name):
    scene = load_scene(name)
    again = scene_from_archive(scene_to_archive(scene), 'test')
    for field in ('rest_positions', 'mass', 'springs', 'stiffness', 'fixed', 'gravity'):
        np.testing.assert_array_equal(getattr(again, field), getattr(scene, field), field)
    if scene.triangles is not None:                  # a volume's skin
        np.testing.assert_array_equal(again.triangles, scene.triangles)
    if scene.loaded:                                 # the cable hangs as it did
        np.testing.assert_array_equal(again.unloaded_positions, scene.unloaded_positions)
    assert scene_header(again) == scene_header(scene)


def test_a_large_scene_takes_less_room_than_its_yaml_and_is_read_whole():
    scene = load_scene('sheet_100x100')
    data = scene_to_archive(scene)
    assert len(data) < 0.7 * len(scene_to_yaml(scene).encode())
    again = scene_from_archive(data, 'test')
    assert again.n_particles == 10_000 and np.array_equal(again.springs, scene.springs)


def _with(**changes) -> bytes:
    arrays = entries()
    for name, value in changes.items():
        if value is None:
            arrays.pop(name)
        else:
            arrays[name] = value
    return archive(arrays)


@pytest.mark.parametrize('data, message', [
    (b'not a zip file', 'not a readable scene archive: File is not a zip file'),
    (scene_to_archive(load_scene('sheet_10x10'))[:5000], 'not a readable scene archive'),
    (_with(extra=np.zeros(3)), "scene archive has unknown entry 'extra'"),
    (_with(header=None), "scene archive without its header (a text entry 'header')"),
    (_with(header=np.array('- 1\n- 2\n')), 'scene archive header is not a mapping'),
    (_with(header=np.array('name: [')), 'invalid YAML'),
    (_with(positions=np.array(['a', 'b'])), "entry 'positions' holds <U1, not numbers"),
    (_with(pairs=np.zeros(4, dtype=np.int64)), "entry 'pairs' has 1 dimension(s), not 2"),
    (_with(mass=np.array([object()], dtype=object)), 'not a readable scene archive: Object '
     'arrays cannot be loaded when allow_pickle=False'),
    (_with(mass=np.full(100, np.nan)), 'particles.mass[0]: must be finite, got nan'),
    (_with(pairs=np.array([[0, 1], [0, 500]])), 'springs.pairs'),
])
def test_a_bad_archive_is_one_line_naming_the_problem(data, message):
    with pytest.raises(SceneError) as error:
        scene_from_archive(data, 'run.mcap (scene)')
    text = str(error.value)
    assert text.startswith('run.mcap (scene)') and message in text and '\n' not in text


def test_an_archive_declaring_more_than_the_bound_is_refused_before_it_is_read(monkeypatch):
    data = scene_to_archive(load_scene('sheet_10x10'))
    with zipfile.ZipFile(io.BytesIO(data)) as zipped:
        declared = sum(info.file_size for info in zipped.infolist())
    monkeypatch.setattr(scene_archive, 'MAX_ARCHIVE_BYTES', declared - 1)
    monkeypatch.setattr(np, 'load', lambda *a, **k: pytest.fail('read before it was bounded'))
    with pytest.raises(SceneError, match=f'scene archive of {declared:,} bytes is beyond the '):
        scene_from_archive(data, 'test')

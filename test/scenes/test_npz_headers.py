"""
Every ``.npz`` the project reads has its headers read first: a forged one is never allocated.

A header declaring 2.4 TB over 80 bytes is refused, named, by the header reader
(:mod:`modal_spring_ros.scenes.files.npz_headers`) and by each of its readers: a scene archive,
a run compared, a spring-sample cache entry; ``numpy.load`` is never reached.
"""
from __future__ import annotations

import io
import zipfile

from modal_spring_ros.core.forces.samples import CacheEntryError
from modal_spring_ros.core.model.scene import SceneError
from modal_spring_ros.runs.comparison import load_npz_run, RunError
from modal_spring_ros.runs.sample_cache import SampleCache
from modal_spring_ros.scenes.files.npz_headers import declared_arrays
from modal_spring_ros.scenes.files.scene_archive import scene_from_archive, scene_to_archive
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest

HUGE = (10 ** 6, 10 ** 5, 3)                 # 2.4e12 bytes of float64
DAMAGED = (r"damaged: 'positions' declares 2,400,000,000,000 bytes \(\(1000000, 100000, 3\)\), "
           'its entry holds 80')


def forged(shape: tuple[int, ...], name: str = 'positions', version: tuple[int, int] = (1, 0),
           others: dict[str, bytes] | None = None) -> bytes:
    """Return a zip whose ``name`` entry's header declares ``shape`` (float64) over 80 bytes."""
    header = io.BytesIO()
    fields = {'descr': '<f8', 'fortran_order': False, 'shape': shape}
    if version == (1, 0):
        np.lib.format.write_array_header_1_0(header, fields)
    else:
        np.lib.format.write_array_header_2_0(header, fields)
    data = io.BytesIO()
    with zipfile.ZipFile(data, 'w') as archive:
        for other, raw in (others or {}).items():
            archive.writestr(other, raw)
        archive.writestr(f'{name}.npy', header.getvalue() + bytes(80))
    return data.getvalue()


def _npy(array: np.ndarray) -> bytes:
    out = io.BytesIO()
    np.save(out, array)
    return out.getvalue()


@pytest.fixture
def no_allocation(monkeypatch):
    """Fail the test where numpy.load is reached."""
    monkeypatch.setattr(np, 'load', lambda *a, **k: pytest.fail('numpy.load was reached'))


def test_the_headers_say_each_entry_its_shape_and_size_and_refuse_a_forged_one():
    t = np.arange(5.0)
    declared = declared_arrays(forged((10,), others={'t.npy': _npy(t)}))
    assert declared['t'].shape == (5,) and declared['t'].nbytes == 40
    assert declared['positions'].shape == (10,) and declared['positions'].dtype == np.float64
    assert declared_arrays(forged((10,), version=(2, 0)))['positions'].nbytes == 80
    with pytest.raises(ValueError, match=DAMAGED):
        declared_arrays(forged(HUGE))
    with pytest.raises(ValueError, match="'positions' declares 88 bytes"):
        declared_arrays(forged((11,)))                         # one element short: damaged
    with pytest.raises(zipfile.BadZipFile):
        declared_arrays(b'positions')


def test_a_run_with_a_forged_header_is_damaged(tmp_path, no_allocation):
    path = tmp_path / 'forged.npz'
    path.write_bytes(forged(HUGE))
    with pytest.raises(RunError, match=f'{path}: not a modal_spring_sim .npz run: {DAMAGED}'):
        load_npz_run(path, budget=10 ** 15)
    path.write_bytes(forged((10,)))
    with pytest.raises(RunError, match=r"'positions' has the shape \(10,\), not \(frames, "):
        load_npz_run(path)


def test_a_cache_entry_with_a_forged_header_is_refused(tmp_path, no_allocation):
    cache = SampleCache(tmp_path)
    cache.path('entry').write_bytes(forged(HUGE, name='forces'))
    with pytest.raises(CacheEntryError, match=r"unreadable \(ValueError: damaged: 'forces' "):
        cache.load('entry')


def test_a_scene_archive_with_a_forged_header_is_refused(monkeypatch):
    with zipfile.ZipFile(io.BytesIO(scene_to_archive(load_scene('sheet_10x10')))) as archive:
        kept = {info.filename: archive.read(info) for info in archive.infolist()
                if info.filename != 'mass.npy'}
    data = forged((10 ** 9,), name='mass', others=kept)
    monkeypatch.setattr(np, 'load', lambda *a, **k: pytest.fail('numpy.load was reached'))
    with pytest.raises(SceneError, match=r"^test: not a readable scene archive: damaged: 'mass' "
                       r'declares 8,000,000,000 bytes'):
        scene_from_archive(data, 'test')

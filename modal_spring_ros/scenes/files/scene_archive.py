"""
A scene as an archive of arrays: how the project's bags and runs keep the scene they ran.

:func:`~modal_spring_ros.scenes.files.writing.scene_to_yaml` lists every particle and spring as
YAML text, right for a file a person reads, but a 100k-particle sheet takes 22 MB of it: beyond the
16 MiB a scene's text may have (:mod:`~modal_spring_ros.scenes.files.yaml_reading`), and seconds to
write and tens of seconds to read. Here the scene's arrays (positions, masses, spring pairs and
stiffness, fixed particles, triangles, bending hinges:
:data:`~modal_spring_ros.scenes.files.writing.ARRAY_PLACES`) are kept as ``.npy`` entries of an
uncompressed ``.npz`` archive, beside a ``header`` entry with the rest of the definition as YAML:
12 MB for that sheet, written in a tenth of a second.

Read back, an archive is input like any scene file: its entries are checked before any is
loaded (known names only, at most :data:`MAX_ARCHIVE_BYTES` declared, no pickled objects), each
array's type and shape next, and then the header with the arrays in their places goes through
the scene file's own checks (:func:`~modal_spring_ros.scenes.schema.scene_from_dict`). Each
problem is one :class:`~modal_spring_ros.core.model.scene.SceneError` naming it.
"""
from __future__ import annotations

import io
import zipfile

from modal_spring_ros.core.model.scene import Scene, SceneError
from modal_spring_ros.scenes.files.npz_headers import declared_arrays
from modal_spring_ros.scenes.files.writing import (ARRAY_PLACES, DUMPER, scene_arrays,
                                                   scene_header, with_arrays)
from modal_spring_ros.scenes.files.yaml_reading import load_yaml
from modal_spring_ros.scenes.schema import scene_from_dict, scene_from_yaml
import numpy as np
import yaml

#: the entry holding the definition's other fields, as YAML text
HEADER = 'header'
#: the dimensions of each array: (particles, 3), (springs, 2), (triangles, 3), (hinges, 4),
#: else one
ARRAY_DIMENSIONS = {'positions': 2, 'pairs': 2, 'triangles': 2, 'hinges': 2, 'hinge_weights': 2}
#: most bytes an archive's entries may declare (a 1M-particle sheet takes about 130 MB)
MAX_ARCHIVE_BYTES = 1024 ** 3
#: the media type of an archive stored on its own (an MCAP attachment)
MEDIA_TYPE = 'application/x-npz'


def scene_to_archive(scene: Scene) -> bytes:
    """Return ``scene`` as the bytes of an ``.npz`` archive (:func:`scene_from_archive`)."""
    buffer = io.BytesIO()
    header = yaml.dump(scene_header(scene), Dumper=DUMPER, sort_keys=False)
    np.savez(buffer, **{HEADER: np.array(header)}, **scene_arrays(scene))
    return buffer.getvalue()


def scene_from_archive(data: bytes, source: str) -> Scene:
    """
    Return the scene an archive of :func:`scene_to_archive` holds.

    :raises SceneError: not such an archive, or a scene the scene file's checks refuse.
    """
    arrays = _entries(data, source)
    header = arrays.pop(HEADER, None)
    if header is None or header.dtype.kind != 'U' or header.ndim != 0:
        raise SceneError(f'{source}: scene archive without its header (a text entry '
                         f"'{HEADER}')")
    for name, array in arrays.items():
        if array.dtype.kind not in 'fiu':
            raise SceneError(f'{source}: scene archive entry {name!r} holds {array.dtype}, '
                             'not numbers')
        if array.ndim != ARRAY_DIMENSIONS.get(name, 1):
            raise SceneError(f'{source}: scene archive entry {name!r} has {array.ndim} '
                             f'dimension(s), not {ARRAY_DIMENSIONS.get(name, 1)}')
    definition = load_yaml(str(header[()]), f'{source} (header)')
    if not isinstance(definition, dict):
        raise SceneError(f'{source}: scene archive header is not a mapping')
    return scene_from_dict(with_arrays(definition, {n: a.tolist() for n, a in arrays.items()}),
                           source=source)


def recorded_scene(archive: bytes | None, yaml_text: str | None, source: str) -> Scene | None:
    """
    Return the scene a run's record holds: its ``archive``, else its YAML text, else None.

    Bags and runs written before scenes were archived hold the YAML text of
    :func:`~modal_spring_ros.scenes.files.writing.scene_to_yaml`.
    """
    if archive is not None:
        return scene_from_archive(archive, source)
    if yaml_text is not None:
        return scene_from_yaml(yaml_text, source=source)
    return None


def _entries(data: bytes, source: str) -> dict[str, np.ndarray]:
    """Return an archive's entries, once their names and declared sizes are within bounds."""
    known = set(ARRAY_PLACES) | {HEADER}
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as archive:
            infos = archive.infolist()
        names = [info.filename.removesuffix('.npy') for info in infos]
        unknown = sorted(set(names) - known)
        if unknown or len(set(names)) != len(names):
            what = f'unknown entry {unknown[0]!r}' if unknown else 'an entry twice'
            raise SceneError(f'{source}: scene archive has {what} (entries: '
                             f"{', '.join(sorted(known))})")
        declared = sum(info.file_size for info in infos)
        if declared > MAX_ARCHIVE_BYTES:
            raise SceneError(f'{source}: scene archive of {declared:,} bytes is beyond the '
                             f'{MAX_ARCHIVE_BYTES:,} a scene may have')
        declared_arrays(data)           # headers first: a damaged one is never allocated
        with np.load(io.BytesIO(data), allow_pickle=False) as npz:
            return {name: npz[name] for name in npz.files}
    except SceneError:
        raise
    except Exception as exc:  # noqa: B902 - a damaged archive's any failure is the archive's
        problem = ' '.join(str(exc).split()) or type(exc).__name__
        raise SceneError(f'{source}: not a readable scene archive: {problem}') from None

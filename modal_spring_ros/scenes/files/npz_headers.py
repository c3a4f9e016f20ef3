"""
What an ``.npz`` archive's arrays declare, read from their headers before any array is.

``numpy.load`` allocates what an array's header declares, then reads into it: a header that
declares terabytes over a few bytes (a damaged or forged file) costs an allocation the machine
may not have before the read fails. Every ``.npz`` the project reads (a scene archive, a run, a
sample cache entry) is input, so its headers are read first (:func:`declared_arrays`): each
entry's shape and byte size, and an entry declaring more than it holds, or not an ``.npy``
array of format 1.0 or 2.0, is refused, named.
"""
from __future__ import annotations

import dataclasses
import io
import math
from pathlib import Path
import zipfile

import numpy as np


@dataclasses.dataclass(frozen=True)
class DeclaredArray:
    """An entry's header: its shape, element type and the bytes it takes."""

    shape: tuple[int, ...]
    dtype: np.dtype
    nbytes: int


def declared_arrays(source: str | Path | bytes) -> dict[str, DeclaredArray]:
    """
    Return every entry's declared array by name (without ``.npy``), reading headers only.

    ``source``: a file or an archive's bytes.

    :raises ValueError: an entry not an ``.npy`` array of format 1.0 or 2.0, or declaring more
        bytes than it holds (a damaged file); ``zipfile.BadZipFile``: not a zip archive.
    """
    opened = io.BytesIO(source) if isinstance(source, bytes) else source
    declared = {}
    with zipfile.ZipFile(opened) as archive:
        for info in archive.infolist():
            name = info.filename.removesuffix('.npy')
            with archive.open(info) as fh:
                version = np.lib.format.read_magic(fh)
                if version == (1, 0):
                    shape, _, dtype = np.lib.format.read_array_header_1_0(fh)
                elif version == (2, 0):
                    shape, _, dtype = np.lib.format.read_array_header_2_0(fh)
                else:
                    raise ValueError(f'{name!r} is in .npy format {version}, not 1.0 or 2.0')
                held = info.file_size - fh.tell()
            nbytes = math.prod(shape) * dtype.itemsize
            if nbytes > held:
                raise ValueError(f'damaged: {name!r} declares {nbytes:,} bytes ({shape}), its '
                                 f'entry holds {max(held, 0):,}')
            declared[name] = DeclaredArray(tuple(shape), dtype, nbytes)
    return declared

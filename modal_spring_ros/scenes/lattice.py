"""Regular lattices: the spring pairs of a grid of particles, by kind of neighbour."""
from __future__ import annotations

import itertools

import numpy as np


def lattice_springs(counts: tuple[int, ...], kinds) -> np.ndarray:
    """
    Spring pairs of a regular lattice with ``counts`` particles per axis (x fastest).

    ``kinds``: any of ``edges`` (axis neighbours), ``diagonals`` (both diagonals of every
    face cell) and ``body_diagonals`` (the four diagonals of every 3D cell).
    """
    dims = len(counts)
    index = np.arange(int(np.prod(counts))).reshape(tuple(reversed(counts)))  # [z][y][x]
    index = index.transpose(tuple(reversed(range(dims))))  # [x][y][z]
    offsets: list[tuple[int, ...]] = []
    for kind in kinds:
        for off in itertools.product((-1, 0, 1), repeat=dims):
            nz = sum(1 for o in off if o != 0)
            if kind == 'edges' and nz == 1 and max(off) == 1:
                offsets.append(off)
            elif kind == 'diagonals' and nz == 2:
                # one representative of each +/- pair: first non-zero component positive
                if next(o for o in off if o != 0) == 1:
                    offsets.append(off)
            elif kind == 'body_diagonals' and nz == 3 and off[0] == 1:
                offsets.append(off)
    pairs = []
    for off in dict.fromkeys(offsets):
        src = tuple(slice(max(0, -o), c - max(0, o)) for o, c in zip(off, counts))
        dst = tuple(slice(max(0, o), c - max(0, -o)) for o, c in zip(off, counts))
        a = index[src].ravel()
        b = index[dst].ravel()
        pairs.append(np.stack([np.minimum(a, b), np.maximum(a, b)], axis=1))
    out = np.concatenate(pairs) if pairs else np.empty((0, 2), dtype=np.int64)
    out = out[np.lexsort((out[:, 1], out[:, 0]))]
    return out.astype(np.int64)

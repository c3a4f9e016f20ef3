"""
Which points lie inside a closed triangle surface: the parity of an upward ray's crossings.

A point is inside when a ray from it along +z crosses the surface an odd number of times. The
triangles are binned on an x-y grid, so that each point is tested only against the triangles
whose shadow covers its cell (a few, on a fine mesh), all points of a chunk at once. The query
points are shifted by a tiny irrational amount across z, so that a ray through a vertex or along
an edge of the mesh (a lattice point beneath a lattice-aligned mesh) is not counted twice.
"""
from __future__ import annotations

import numpy as np

#: points tested at once (bounds the candidate pairs held)
CHUNK = 20_000


def inside_closed_surface(points: np.ndarray, vertices: np.ndarray,
                          triangles: np.ndarray) -> np.ndarray:
    """Return (m,) bool: each point inside the closed surface ``vertices[triangles]``."""
    corners = vertices[triangles]                                  # (T, 3, 3)
    low, high = corners[:, :, :2].min(axis=1), corners[:, :, :2].max(axis=1)
    origin = vertices[:, :2].min(axis=0)
    extent = np.maximum(vertices[:, :2].max(axis=0) - origin, 1e-300)
    cells = max(1, int(np.sqrt(triangles.shape[0]) / 2))
    size = extent / cells
    first = np.clip(((low - origin) / size).astype(np.int64), 0, cells - 1)
    last = np.clip(((high - origin) / size).astype(np.int64), 0, cells - 1)
    span = last - first + 1
    count = span[:, 0] * span[:, 1]
    owner = np.repeat(np.arange(triangles.shape[0]), count)        # (triangle, cell) pairs
    offset = np.arange(owner.size) - np.repeat(np.cumsum(count) - count, count)
    cx = first[owner, 0] + offset % span[owner, 0]
    cy = first[owner, 1] + offset // span[owner, 0]
    cell_of_pair = cx * cells + cy
    order = np.argsort(cell_of_pair, kind='stable')
    cell_sorted, owner_sorted = cell_of_pair[order], owner[order]
    shift = np.array([np.sqrt(2.0), np.sqrt(3.0)]) * 1e-7 * float(extent.max())
    out = np.empty(points.shape[0], dtype=bool)
    for start in range(0, points.shape[0], CHUNK):
        p = np.array(points[start:start + CHUNK], dtype=float)
        p[:, :2] += shift
        pc = np.clip(((p[:, :2] - origin) / size).astype(np.int64), 0, cells - 1)
        cell = pc[:, 0] * cells + pc[:, 1]
        lo = np.searchsorted(cell_sorted, cell, 'left')
        hi = np.searchsorted(cell_sorted, cell, 'right')
        n = hi - lo
        point = np.repeat(np.arange(p.shape[0]), n)
        pair = np.repeat(lo, n) + np.arange(point.size) - np.repeat(np.cumsum(n) - n, n)
        crossed = _crosses_above(p[point], corners[owner_sorted[pair]])
        out[start:start + p.shape[0]] = np.bincount(point[crossed],
                                                    minlength=p.shape[0]) % 2 == 1
    return out


def _crosses_above(p: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Tell for each (point, triangle) pair whether the point's upward ray crosses it."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]

    def edge(u, v):  # twice the signed area of (u, v, p) in x-y
        return ((v[:, 0] - u[:, 0]) * (p[:, 1] - u[:, 1])
                - (v[:, 1] - u[:, 1]) * (p[:, 0] - u[:, 0]))

    wa, wb, wc = edge(b, c), edge(c, a), edge(a, b)
    total = wa + wb + wc
    inside = ((wa >= 0) & (wb >= 0) & (wc >= 0) | (wa <= 0) & (wb <= 0) & (wc <= 0)) & (
        total != 0)
    z = (wa * a[:, 2] + wb * b[:, 2] + wc * c[:, 2]) / np.where(total != 0, total, 1.0)
    return inside & (z > p[:, 2])

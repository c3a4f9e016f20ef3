"""
A mesh made a mass-spring network: particles, springs, masses and stiffness from a material.

**Surfaces** (cloth, shells): a spring on every triangle edge; each vertex carries a third of its
triangles' area times ``density`` (kg/m^2). ``bending`` is the bending stiffness ``D`` (N m, as
a plate's ``E t^3 / 12``). A surface flat as built (a cloth, a flag; within 1e-4 of its size
of a plane, and then moved onto it) bends by the quadratic
bending model (:mod:`~modal_spring_ros.core.model.bending`): a fold of ``theta`` across an
interior edge ``e`` costs ``1/2 c_e theta^2``, ``c_e = 3 D |e|^2 / (A_1 + A_2)``, what converges
as the mesh is refined. A surface curved as built (a shell) bends by a spring across every
interior edge, between the two vertices opposite it, of stiffness ``c_e / l^2`` (``l`` its
length): a curved hinge's fold changes that distance at first order.

**Volumes** (solids): a tetrahedral mesh's edges are the springs; a closed surface is filled
first: points on a regular lattice inside it (spaced so that there are about as many as the
surface has vertices, none closer than half a spacing to the skin) and the skin's own vertices
are tetrahedralised together (Delaunay, scipy's Qhull), and the tetrahedra whose centres lie
outside the surface are dropped. The skin's vertices stay particles, so the object shows its own
triangles as it moves; no mesher is needed beyond scipy. Each vertex carries a quarter of its
tetrahedra's volume times ``density`` (kg/m^3).

**Stiffness** per spring follows Van Gelder's rule for spring meshes (Van Gelder 1998,
"Approximate simulation of elastic membranes by triangulated spring meshes"): a spring gets
``stiffness * (sum of its cells' areas or volumes) / length^2``, so that a finer mesh of the same
object has the same low frequencies (a surface's ``stiffness`` is a membrane stiffness, N/m, like
``E t``; a volume's a modulus, Pa).

Every problem is a :class:`~modal_spring_ros.core.model.scene.SceneError` naming the mesh and
what is wrong with it (no cells, degenerate or duplicate cells, an open surface where a volume
needs a closed one).
"""
from __future__ import annotations

import dataclasses

from modal_spring_ros.core.model.bending import (Bending, flat_surface_bending, flattened,
                                                 hinge_quads, is_flat)
from modal_spring_ros.core.model.integer_rows import unique_rows
from modal_spring_ros.core.model.scene import SceneError
from modal_spring_ros.scenes.meshes.inside import inside_closed_surface
from modal_spring_ros.scenes.meshes.mesh_files import MeshData
import numpy as np
from scipy.spatial import cKDTree, Delaunay

#: a cell whose area (volume) is below this share of the mesh's size squared (cubed) is
#: degenerate
DEGENERATE_RTOL = 1e-12


@dataclasses.dataclass(frozen=True)
class Material:
    """``density`` kg/m^2 (surface) or kg/m^3 (volume); ``stiffness`` N/m or Pa; ``bending``."""

    density: float
    stiffness: float
    bending: float = 0.0


@dataclasses.dataclass(frozen=True)
class Network:
    """Particles (n, 3), masses (n,), springs (E, 2) i < j, stiffness (E,), skin, bending."""

    positions: np.ndarray
    mass: np.ndarray
    springs: np.ndarray
    stiffness: np.ndarray
    triangles: np.ndarray
    bending: Bending | None = None


def surface_network(mesh: MeshData, material: Material, name: str) -> Network:
    """Return the network of a surface mesh (see the module text)."""
    tri = _checked_triangles(mesh, name)
    x = mesh.vertices
    area = _areas(x, tri)
    edges, owners = _cell_edges(tri, ((0, 1), (1, 2), (2, 0)))
    area_sum = np.bincount(owners[1], weights=area[owners[0]], minlength=len(edges))
    bending = None
    flat = material.bending > 0.0 and is_flat(x)
    if flat:
        x = flattened(x)   # moved by at most FLAT_SURFACE_RTOL of its size: exactly flat
        bending = flat_surface_bending(x, tri, material.bending)
    pairs, stiffness = [edges], [material.stiffness * area_sum / _lengths(x, edges) ** 2]
    if material.bending > 0.0 and not flat:
        quads, cells = hinge_quads(tri)
        span = quads[:, 2:]
        keep = _lengths(x, span) > 0.0
        fold = (3.0 * material.bending * _lengths(x, quads[:, :2]) ** 2
                / area[cells].sum(axis=1))
        pairs.append(np.sort(span[keep], axis=1))
        stiffness.append(fold[keep] / _lengths(x, span[keep]) ** 2)
    mass = material.density * np.bincount(tri.ravel(), weights=np.repeat(area / 3.0, 3),
                                          minlength=len(x))
    springs, k = _merged_pairs(np.concatenate(pairs), np.concatenate(stiffness))
    return Network(x, mass, springs, k, tri, bending)


def volume_network(mesh: MeshData, material: Material, name: str) -> Network:
    """Return the network of a volume: its tetrahedra, or its closed surface filled."""
    if mesh.tetrahedra.size:
        x, tet = mesh.vertices, mesh.tetrahedra
        skin = _boundary_faces(tet)
    else:
        skin = _checked_triangles(mesh, name)
        _check_closed(skin, name)
        x, tet = _filled(mesh.vertices, skin)
    volume = np.abs(np.einsum('ij,ij->i', x[tet[:, 1]] - x[tet[:, 0]], np.cross(
        x[tet[:, 2]] - x[tet[:, 0]], x[tet[:, 3]] - x[tet[:, 0]]))) / 6.0
    size = float(np.max(np.ptp(x, axis=0)))
    flat = np.flatnonzero(volume <= DEGENERATE_RTOL * size ** 3)
    if mesh.tetrahedra.size and flat.size:
        raise SceneError(f'mesh {name}: tetrahedron {int(flat[0])} is degenerate (no volume)'
                         + (f' and {flat.size - 1} more' if flat.size > 1 else ''))
    tet, volume = tet[volume > DEGENERATE_RTOL * size ** 3], volume[
        volume > DEGENERATE_RTOL * size ** 3]
    edges, owners = _cell_edges(tet, ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)))
    volume_sum = np.bincount(owners[1], weights=volume[owners[0]], minlength=len(edges))
    mass = material.density * np.bincount(tet.ravel(), weights=np.repeat(volume / 4.0, 4),
                                          minlength=len(x))
    return Network(x, mass, edges, material.stiffness * volume_sum / _lengths(x, edges) ** 2,
                   skin)


def _checked_triangles(mesh: MeshData, name: str) -> np.ndarray:
    tri = mesh.triangles
    if not tri.size:
        raise SceneError(f'mesh {name}: has no triangles')
    size = float(np.max(np.ptp(mesh.vertices, axis=0)))
    area = _areas(mesh.vertices, tri)
    bad = np.flatnonzero((area <= DEGENERATE_RTOL * size ** 2)
                         | (np.sort(tri, axis=1)[:, :-1] == np.sort(tri, axis=1)[:, 1:]).any(1))
    if bad.size:
        raise SceneError(f'mesh {name}: triangle {int(bad[0])} is degenerate (no area)'
                         + (f' and {bad.size - 1} more' if bad.size > 1 else ''))
    _, first, counts = unique_rows(np.sort(tri, axis=1), return_index=True,
                                   return_counts=True)
    if np.any(counts > 1):
        twice = int(np.sort(first[counts > 1])[0])
        raise SceneError(f'mesh {name}: triangle {twice} is listed more than once '
                         f'({int(np.sum(counts[counts > 1] - 1))} duplicate triangles)')
    return tri


def _check_closed(tri: np.ndarray, name: str) -> None:
    edges, owners = _cell_edges(tri, ((0, 1), (1, 2), (2, 0)))
    per_edge = np.bincount(owners[1], minlength=len(edges))
    open_edges, shared = int(np.sum(per_edge == 1)), int(np.sum(per_edge > 2))
    if open_edges or shared:
        raise SceneError(
            f'mesh {name}: a volume needs a closed surface, and this one has '
            + ' and '.join(filter(None, (
                f'{open_edges} edges on one triangle only (holes)' if open_edges else '',
                f'{shared} edges on more than two triangles (not manifold)' if shared else '')))
            + '; give kind: surface, or a closed or tetrahedral mesh')


def _filled(vertices: np.ndarray, skin: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Skin vertices plus interior lattice points, tetrahedralised, outside cells dropped."""
    low, high = vertices.min(axis=0), vertices.max(axis=0)
    corners = vertices[skin]
    enclosed = abs(float(np.sum(np.einsum('ij,ij->i', corners[:, 0], np.cross(
        corners[:, 1], corners[:, 2]))))) / 6.0
    spacing = (enclosed / max(len(vertices), 1)) ** (1.0 / 3.0)
    axes = [np.arange(lo + 0.5 * spacing, hi, spacing) for lo, hi in zip(low, high)]
    grid = np.stack(np.meshgrid(*axes, indexing='ij'), axis=-1).reshape(-1, 3)
    if grid.size:
        grid = grid[inside_closed_surface(grid, vertices, skin)]
        far = cKDTree(vertices).query(grid)[0] >= 0.5 * spacing
        grid = grid[far]
    points = np.concatenate([vertices, grid])
    cells = Delaunay(points).simplices.astype(np.int64)
    centre = points[cells].mean(axis=1)
    return points, cells[inside_closed_surface(centre, vertices, skin)]


def _boundary_faces(tet: np.ndarray) -> np.ndarray:
    """Triangles that belong to one tetrahedron only: the solid's skin."""
    faces = tet[:, [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]]].reshape(-1, 3)
    _, first, counts = unique_rows(np.sort(faces, axis=1), return_index=True,
                                   return_counts=True)
    return faces[np.sort(first[counts == 1])]


def _areas(x: np.ndarray, tri: np.ndarray) -> np.ndarray:
    return 0.5 * np.linalg.norm(np.cross(x[tri[:, 1]] - x[tri[:, 0]],
                                         x[tri[:, 2]] - x[tri[:, 0]]), axis=1)


def _lengths(x: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    return np.linalg.norm(x[pairs[:, 1]] - x[pairs[:, 0]], axis=1)


def _cell_edges(cells: np.ndarray, local: tuple[tuple[int, int], ...]
                ) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the unique edges (E, 2) of ``cells`` and their owners.

    The owners: (2, C * len(local)) cell index and edge index of every cell's every edge.
    """
    ends = np.stack([np.sort(cells[:, list(pair)], axis=1) for pair in local], axis=1)
    edges, index = unique_rows(ends.reshape(-1, 2), return_inverse=True)
    cell = np.repeat(np.arange(cells.shape[0]), len(local))
    return edges.astype(np.int64), np.stack([cell, index.ravel()])


def _merged_pairs(pairs: np.ndarray, stiffness: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One spring per particle pair: springs listed twice act as one, their stiffness summed."""
    unique, index = unique_rows(pairs, return_inverse=True)
    return unique.astype(np.int64), np.bincount(index.ravel(), weights=stiffness)

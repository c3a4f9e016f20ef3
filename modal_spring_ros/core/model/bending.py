"""
Bending of a surface flat as built: the quadratic (isometric) bending model.

A cloth resists folding. Springs across its hinges cannot say so about a flat shape: the distance
between the two vertices across a flat hinge changes only to second order in the fold angle, so
such a spring's energy grows with its fourth power and a flat cloth has no stiffness against
folding at first order; which wrinkles it hangs in then depends on the mesh. The quadratic bending
model (Bergou, Wardetzky, Harmon, Zorin, Grinspun 2006, "A quadratic bending model for
inextensible surfaces") gives each interior edge ``e`` (vertices ``i, j``, the two opposite
ones ``k, l``) the energy

    E_e = 1/2 c_e |w_i x_i + w_j x_j + w_k x_k + w_l x_l|^2,   c_e = 3 D |e|^2 / (A_1 + A_2),

with ``w`` the hinge's weights: the one direction (up to scale) that vanishes on every affine
function of the flat shape (sums to zero, weights the four rest positions to zero). Scaled so
that turning one triangle by a small angle ``theta`` about the edge gives ``|sum w x| = theta``,
``E_e = 1/2 c_e theta^2``: the discrete-shell energy of a fold, with ``D`` the bending stiffness
(N m). For bends that do not stretch the surface the energy is exact and converges as the mesh
is refined; it is zero for every rigid motion; and it is quadratic in the positions, so its
force is linear, ``-B x``, and its Hessian a constant sparse ``B`` (``kron(B, I_3)`` on the
coordinates). Stored per hinge as the particles and the weights times ``sqrt(c_e)``.
"""
from __future__ import annotations

import dataclasses

from modal_spring_ros.core.model.integer_rows import unique_rows
import numpy as np
import scipy.sparse as sp

#: a surface is flat when its vertices lie within this share of its size of one plane (a mesh
#: file's coordinates written to six decimals are off their plane by about 1e-6 of its size)
FLAT_SURFACE_RTOL = 1e-4


@dataclasses.dataclass(frozen=True, eq=False)
class Bending:
    """
    Hinges (H, 4) of particles and their weights (H, 4): energy ``1/2 sum_h |sum_i w_hi x_hi|^2``.

    The weights include the hinge's stiffness (``sqrt(c_e)``, see the module text).
    """

    hinges: np.ndarray
    weights: np.ndarray

    @property
    def count(self) -> int:
        return int(self.hinges.shape[0])

    def matrix(self, n_particles: int) -> sp.csr_matrix:
        """Return the (n, n) sparse ``B``, ``sum_h w_h w_h^T`` on each hinge's particles."""
        rows = np.repeat(self.hinges, 4, axis=1).ravel()
        cols = np.tile(self.hinges, (1, 4)).ravel()
        vals = (self.weights[:, :, None] * self.weights[:, None, :]).ravel()
        return sp.coo_matrix((vals, (rows, cols)), shape=(n_particles, n_particles)).tocsr()

    def residual(self, positions: np.ndarray) -> np.ndarray:
        """Return each hinge's ``|sum_i w_i x_i|`` at ``positions`` (n, d): 0 on the rest shape."""
        bent = np.einsum('hi,hid->hd', self.weights, positions[self.hinges])
        return np.linalg.norm(bent, axis=1)


def is_flat(points: np.ndarray) -> bool:
    """Tell whether the points lie in one plane (within :data:`FLAT_SURFACE_RTOL` of its size)."""
    centred = points - points.mean(axis=0)
    values = np.linalg.svd(centred, compute_uv=False)
    return bool(values.size >= 3 and values[2] <= FLAT_SURFACE_RTOL * values[0])


def flattened(points: np.ndarray) -> np.ndarray:
    """
    Return the points moved onto the plane that fits them best (least squares).

    Points already in it to round-off (within 1e-12 of their extent) are returned as they are.
    """
    centre = points.mean(axis=0)
    normal = np.linalg.svd(points - centre, full_matrices=False)[2][2]
    off = (points - centre) @ normal
    if np.max(np.abs(off)) <= 1e-12 * float(np.max(np.ptp(points, axis=0))):
        return points
    return points - np.outer(off, normal)


def hinge_quads(triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """
    Return each edge shared by exactly two triangles as (i, j, k, l), and those two triangles.

    ``i, j`` the edge's ends, ``k`` the corner opposite it in the first triangle, ``l`` in the
    second; the triangles as (H, 2) indices.
    """
    tri = np.asarray(triangles, dtype=np.int64)
    # edge c of a triangle joins corners c and c + 1; the corner opposite it is c + 2
    ends = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    opposite = np.concatenate([tri[:, 2], tri[:, 0], tri[:, 1]])
    owner = np.tile(np.arange(tri.shape[0]), 3)
    edges, index, counts = unique_rows(ends, return_inverse=True, return_counts=True)
    order = np.argsort(index.ravel(), kind='stable')
    starts = np.cumsum(counts) - counts
    two = np.flatnonzero(counts == 2)
    first, second = order[starts[two]], order[starts[two] + 1]
    quads = np.column_stack([edges[two], opposite[first], opposite[second]])
    keep = quads[:, 2] != quads[:, 3]
    return quads[keep], np.column_stack([owner[first], owner[second]])[keep]


def flat_surface_bending(positions: np.ndarray, triangles: np.ndarray,
                         stiffness: float) -> Bending:
    """
    Return the quadratic bending of a surface flat as built, bending stiffness ``stiffness``.

    ``positions`` (n, 3) must lie in one plane (:func:`is_flat`, :func:`flattened`); the weights
    are found in its own coordinates, so that they vanish on the shape as built to round-off.
    """
    x = np.asarray(positions, dtype=float)
    centred = x - x.mean(axis=0)
    plane = np.linalg.svd(centred, full_matrices=False)[2][:2]     # the plane's two directions
    flat = centred @ plane.T                                         # (n, 2)
    quads, _ = hinge_quads(triangles)
    corner = flat[quads]                                             # (H, 4, 2)
    # the weights span the null space of [1; X^T] (three conditions on four numbers): its
    # cofactors, each the signed area of the triangle of the other three corners
    weights = np.stack([(-1) ** j * _cross2(corner[:, b] - corner[:, a],
                                            corner[:, c] - corner[:, a])
                        for j, (a, b, c) in enumerate(((1, 2, 3), (0, 2, 3), (0, 1, 3),
                                                       (0, 1, 2)))], axis=1)   # (H, 4)
    edge = corner[:, 1] - corner[:, 0]
    length = np.linalg.norm(edge, axis=1)
    area = 0.5 * np.abs(np.stack([_cross2(edge, corner[:, 2] - corner[:, 0]),
                                  _cross2(edge, corner[:, 3] - corner[:, 0])], axis=1))
    # a fold of theta of the first triangle moves its corner by (its height) theta
    weights /= (weights[:, 2] * 2.0 * area[:, 0] / length)[:, None]
    factor = np.sqrt(3.0 * stiffness * length ** 2 / area.sum(axis=1))
    hinges = quads.copy()
    scaled = weights * factor[:, None]
    hinges.setflags(write=False)
    scaled.setflags(write=False)
    return Bending(hinges, scaled)


def _cross2(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]

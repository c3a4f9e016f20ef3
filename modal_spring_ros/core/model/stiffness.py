"""
Linear stiffness of a mass-spring network at its rest shape (paper eqs. 3-13), assembled sparse.

A spring of stiffness ``k`` acts along its own axis with ``k [[1, -1], [-1, 1]]`` (eq. 6);
rotated into world axes by ``T`` (eq. 9) its element matrix is ``T^T Kbar T`` (eq. 13), whose
``d x d`` blocks are ``+-k u u^T`` with ``u`` the unit direction at rest. The element matrices
are scatter-added into a sparse global matrix; the fixed particles' rows and columns are then
dropped, as in the paper's 1D example.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp


def rotation_matrix_2d(theta: float) -> np.ndarray:
    """
    Return the paper's ``T`` (eq.

    9) for a 2D spring at angle ``theta``: world -> spring axes.
    """
    c, s = np.cos(theta), np.sin(theta)
    r = np.array([[c, s], [-s, c]])
    t = np.zeros((4, 4))
    t[:2, :2] = r
    t[2:, 2:] = r
    return t


def local_stiffness_2d(k: float) -> np.ndarray:
    """Return the paper's ``Kbar`` (eq. 6): a spring's stiffness in its own axes."""
    kbar = np.zeros((4, 4))
    kbar[np.ix_([0, 2], [0, 2])] = k * np.array([[1.0, -1.0], [-1.0, 1.0]])
    return kbar


def element_stiffness(k: float, direction: np.ndarray) -> np.ndarray:
    """Return the ``2d x 2d`` element matrix of one spring with unit ``direction`` (any d)."""
    u = np.asarray(direction, dtype=float)
    block = k * np.outer(u, u)
    return np.block([[block, -block], [-block, block]])


def assemble_stiffness(positions: np.ndarray, springs: np.ndarray, stiffness: np.ndarray,
                       dimension: int, rest_length: np.ndarray | None = None,
                       compression: bool = True) -> sp.csr_matrix:
    """
    Global ``(n d) x (n d)`` stiffness at ``positions``; DOF ``p * d + axis``; vectorised COO.

    ``positions`` holds the ``dimension`` moving coordinates of each particle. Without
    ``rest_length`` every spring is at its rest length there (the paper's rest stiffness, eq. 13:
    blocks ``k u u^T``). With it, the tangent stiffness of stretched springs: each block gains the
    geometric term ``k (1 - l/L) (I - u u^T)`` of its tension, what gives a hanging cloth or cable
    its stiffness across itself. ``compression=False`` leaves that term out of compressed springs
    (a positive semi-definite stiffness, for the descent of :mod:`.loaded_shape`).
    """
    x = np.asarray(positions, dtype=float)[:, :dimension]
    i, j = springs[:, 0], springs[:, 1]
    delta = x[j] - x[i]
    length = np.linalg.norm(delta, axis=1)
    u = delta / length[:, None]
    blocks = stiffness[:, None, None] * u[:, :, None] * u[:, None, :]  # (E, d, d)
    if rest_length is not None:
        tension = stiffness * (1.0 - rest_length / length)
        if not compression:
            tension = np.maximum(tension, 0.0)
        blocks += tension[:, None, None] * (np.eye(dimension) - u[:, :, None] * u[:, None, :])
    a = np.arange(dimension)
    # DOF indices of each block entry (E, d, d)
    ri = (i[:, None] * dimension + a)[:, :, None].repeat(dimension, 2)
    ci = (i[:, None] * dimension + a)[:, None, :].repeat(dimension, 1)
    rj = (j[:, None] * dimension + a)[:, :, None].repeat(dimension, 2)
    cj = (j[:, None] * dimension + a)[:, None, :].repeat(dimension, 1)
    rows = np.concatenate([ri, rj, ri, rj]).ravel()
    cols = np.concatenate([ci, cj, cj, ci]).ravel()
    vals = np.concatenate([blocks, blocks, -blocks, -blocks]).ravel()
    n = x.shape[0] * dimension
    return sp.coo_matrix((vals, (rows, cols)), shape=(n, n)).tocsr()


def reduce_to_free(matrix: sp.spmatrix, free_dof: np.ndarray) -> sp.csr_matrix:
    """Rows and columns of the free DOF only (boundary condition of fixed particles)."""
    m = sp.csr_matrix(matrix)
    return m[free_dof][:, free_dof].tocsr()

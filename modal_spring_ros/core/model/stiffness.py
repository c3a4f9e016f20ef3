"""
Linear stiffness of a mass-spring network at its rest shape (paper eqs. 3-13), assembled sparse.

A spring of stiffness ``k`` acts along its own axis with ``k [[1, -1], [-1, 1]]`` (eq. 6);
rotated into world axes by ``T`` (eq. 9) its element matrix is ``T^T Kbar T`` (eq. 13), whose
``d x d`` blocks are ``+-k u u^T`` with ``u`` the unit direction at rest. The element matrices
are scatter-added into a sparse global matrix; the fixed particles' rows and columns are then
dropped, as in the paper's 1D example.
"""
from __future__ import annotations

from modal_spring_ros.core.laws import SpringLaw
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


def assemble_stiffness(positions: np.ndarray, springs: np.ndarray, law: SpringLaw,
                       dimension: int, stretched: bool = False,
                       compression: bool = True) -> sp.csr_matrix:
    """
    Global ``(n d) x (n d)`` stiffness at ``positions``; DOF ``p * d + axis``; vectorised COO.

    ``positions`` holds the ``dimension`` moving coordinates of each particle; ``law`` is the
    springs' (:mod:`modal_spring_ros.core.laws`). Unless ``stretched`` every spring is taken at
    its rest length there (the paper's rest stiffness, eq. 13: blocks ``f'(l) u u^T``, ``k u u^T``
    for the linear spring). ``stretched``: the tangent stiffness at the springs' lengths there,
    the law's ``a I + b u u^T`` (``a = f / L``: the geometric term of the tension, what gives a
    hanging cloth or cable its stiffness across itself). ``compression=False`` leaves that term
    out of compressed springs (a positive semi-definite stiffness, for the descent of
    :mod:`.loaded_shape`).
    """
    x = np.asarray(positions, dtype=float)[:, :dimension]
    i, j = springs[:, 0], springs[:, 1]
    delta = x[j] - x[i]
    length = np.linalg.norm(delta, axis=1)
    u = delta / length[:, None]
    outer = u[:, :, None] * u[:, None, :]                           # (E, d, d)
    if stretched:
        tension, along = law.tangent(length)
        along = along + tension                                     # f'(L)
        if not compression:
            tension = np.maximum(tension, 0.0)
        blocks = along[:, None, None] * outer + tension[:, None, None] * (
            np.eye(dimension) - outer)
    else:
        blocks = law.rest_stiffness()[:, None, None] * outer
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

"""
Sparse factors of the symmetric positive definite matrices the core solves with.

SuperLU (scipy's ``splu``) orders the columns of any matrix as if it were unsymmetric (COLAMD)
and pivots for stability. The matrices the core factors are symmetric and definite (a stiffness
shifted by a multiple of the mass, the mass plus a damping or stiffness term, a convex Hessian
plus a Levenberg term): for those a symmetric ordering with the diagonal as pivots is what a
Cholesky factor does, stable without pivoting. Measured with one thread: a 10,000-vertex cloth's
Hessian (30,000 coordinates) factors into 10.5 M entries in 1.0 s with minimum degree on the
structure of ``A + A^T`` against 18.6 M in 2.7 s with COLAMD; ``sheet_100x100``'s shifted
stiffness into 2.9 M against 3.8 M, and each solve takes a third less time.

Given where the particles are, a large matrix is ordered by nested dissection instead
(:mod:`.dissection`): ``sheet_316x316``'s shifted stiffness factors into 35 M entries in 5 s,
ordering included, against minimum degree's 54 M in 10 s.
"""
from __future__ import annotations

from modal_spring_ros.core.model.dissection import nested_dissection
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla


#: the share of its column's largest entry a diagonal pivot needs where the matrix may be
#: indefinite (SuperLU's threshold pivoting, the diagonal preferred)
INDEFINITE_PIVOT_THRESHOLD = 0.1

#: rows from which a matrix whose particles' positions are known is ordered by nested
#: dissection rather than minimum degree
DISSECTION_MIN_ROWS = 2_000

SUPERLU_OPTIONS = {'SymmetricMode': True}


class OrderedFactor:
    """The factor of a matrix whose rows and columns were put in ``order`` before factoring."""

    def __init__(self, factor: spla.SuperLU, order: np.ndarray):
        self._factor = factor
        self._order = order
        self._inverse = np.empty_like(order)
        self._inverse[order] = np.arange(order.size)

    @property
    def nnz(self) -> int:
        """Entries of the factor (both triangles)."""
        return int(self._factor.L.nnz + self._factor.U.nnz)

    @property
    def pivots(self) -> np.ndarray:
        """Return the diagonal of ``U``: the pivots of the elimination."""
        return self._factor.U.diagonal()

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """Return the solution for ``rhs`` (a vector or columns), in the matrix's own order."""
        return self._factor.solve(np.ascontiguousarray(rhs[self._order]))[self._inverse]


def elimination_order(matrix: sp.spmatrix, points: np.ndarray | None) -> np.ndarray | None:
    """
    Return the nested dissection order of a large ``matrix``; None: minimum degree's.

    ``points`` (p, k): the positions of the particles whose coordinates the rows are (in blocks
    per particle), or None. An order fits every matrix of the same size (its fill depends on the
    pattern): matrices of one pattern, factored in turn, can share one.
    """
    if points is None or matrix.shape[0] < DISSECTION_MIN_ROWS:
        return None
    return nested_dissection(matrix, points)


def factor_definite(matrix: sp.spmatrix, definite: bool = True,
                    points: np.ndarray | None = None,
                    order: np.ndarray | None = None) -> spla.SuperLU | OrderedFactor:
    """
    Return the sparse LU factor of a symmetric ``matrix``, positive definite unless told.

    A matrix that may be indefinite (``definite`` false: an exact tangent stiffness) keeps the
    symmetric ordering but pivots off the diagonal where a diagonal entry is too small. The
    rows are eliminated in ``order``, else in :func:`elimination_order`'s from ``points``; the
    factor solves in the matrix's own order either way.
    """
    threshold = 0.0 if definite else INDEFINITE_PIVOT_THRESHOLD
    if order is None:
        order = elimination_order(matrix, points)
    if order is None:
        return spla.splu(sp.csc_matrix(matrix), permc_spec='MMD_AT_PLUS_A',
                         diag_pivot_thresh=threshold, options=SUPERLU_OPTIONS)
    ordered = sp.csr_matrix(matrix)[order][:, order].tocsc()
    return OrderedFactor(spla.splu(ordered, permc_spec='NATURAL', diag_pivot_thresh=threshold,
                                   options=SUPERLU_OPTIONS), order)


def negative_pivots(matrix: sp.spmatrix, order: np.ndarray | None = None,
                    points: np.ndarray | None = None) -> int:
    """
    Return how many eigenvalues of a symmetric ``matrix`` are negative or zero, from one factor.

    Eliminated with its diagonal as the pivots in a symmetric order, a symmetric matrix has as
    many negative pivots as negative eigenvalues (Sylvester's law of inertia); an exactly
    singular one counts as one. Far cheaper than an eigenvalue near zero of a large matrix.
    """
    try:
        factor = factor_definite(matrix, points=points, order=order)
    except RuntimeError:
        return 1
    pivots = factor.pivots if isinstance(factor, OrderedFactor) else factor.U.diagonal()
    return int(np.sum(~(pivots > 0.0)))

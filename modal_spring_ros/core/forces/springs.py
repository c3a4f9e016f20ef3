"""
The springs' geometry, shared by every force model.

``D``, the sparse spring-difference matrix (spring vectors from free-DOF displacements), and the
vectorised pull of a (d, E) array of spring vectors by their law
(:mod:`modal_spring_ros.core.laws`): no Python loop over springs.
"""
from __future__ import annotations

from modal_spring_ros.core.laws import SpringLaw
import numpy as np
import scipy.sparse as sp


def spring_difference_matrix(springs: np.ndarray, free_index: np.ndarray, dimension: int,
                             n_free: int) -> sp.csr_matrix:
    """
    Sparse ``D`` with ``(D u)[a*E + e] = u_j[a] - u_i[a]`` over the free DOF (fixed: 0).

    Rows are component-major (all x components, then all y, ...), so that the per-spring
    arithmetic runs over contiguous rows of a ``(d, E)`` array.
    """
    n_springs = springs.shape[0]
    rows, cols, vals = [], [], []
    for end, sign in ((1, 1.0), (0, -1.0)):
        p = free_index[springs[:, end]]
        ok = p >= 0
        for a in range(dimension):
            rows.append(a * n_springs + np.flatnonzero(ok))
            cols.append(p[ok] * dimension + a)
            vals.append(np.full(int(ok.sum()), sign))
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(n_springs * dimension, n_free * dimension))


def spring_lengths(delta: np.ndarray) -> np.ndarray:
    """Euclidean lengths of the columns of a (d, E) array."""
    length = np.einsum('de,de->e', delta, delta)
    return np.sqrt(length, out=length)


def pull_springs(delta: np.ndarray, law: SpringLaw) -> float:
    """
    Turn the (d, E) spring vectors ``delta`` into the springs' force vectors in place.

    Each pulls with ``f(L) / L (x_j - x_i)`` (``law``'s tension; paper eq. 20 for the linear
    spring: ``k (L - l) / L``). Returns the largest strain ``|L / l - 1|`` (through the largest
    and smallest ``L / l``).
    """
    length = spring_lengths(delta)
    ratio = length * law.inv_l
    strain = max(float(np.maximum.reduce(ratio)) - 1.0, 1.0 - float(np.minimum.reduce(ratio)))
    delta *= law.pull_per_length(length)
    return strain

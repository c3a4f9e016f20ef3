"""
The sparse eigensolver of large scenes: shift-invert Lanczos on a kept factor, here or in a worker.

:class:`ShiftInvertModes` finds the lowest modes of ``K phi = lam M phi`` (``eigsh`` with the
factor of ``K - sigma M`` as its inverse operator) and solves with ``K`` on the same factor. A
:class:`~modal_spring_ros.core.worker.WorkerProcess` runs it through the module-level calls
below, keeping its own copy (and factor) of the solver between calls.
"""
from __future__ import annotations

from typing import Any, Callable
import uuid

from modal_spring_ros.core.model.definite_factor import factor_definite
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

#: Iterative refinement steps of a solve with the shifted factor of the rest stiffness.
REFINEMENT_STEPS = 2


class ShiftInvertModes:
    """
    Lowest modes of ``K phi = lam M phi`` (sparse ``K``, lumped ``M``) by shift-invert Lanczos.

    Mass-normalised and ascending; the sparse LU of ``K - sigma M`` is made on the first call and
    kept for the next ones.
    """

    def __init__(self, stiffness: sp.spmatrix, mass_dof: np.ndarray,
                 points: np.ndarray | None = None):
        self.k = stiffness.tocsc()
        self.mass_dof = np.asarray(mass_dof, dtype=float)
        self.points = points  # where the particles are: the factor's ordering
        self.lam_scale = float(np.max(self.k.diagonal() / self.mass_dof))
        # A small negative shift keeps K - sigma M definite even when K is singular (a
        # mechanism, reported from the modes), and small enough that the same factor solves
        # with K itself after a few refinement steps (see solve).
        self.sigma = -1e-9 * self.lam_scale
        self.token = uuid.uuid4().hex  # names this solver in a worker process
        self._factor = None

    def __getstate__(self) -> dict:
        return dict(self.__dict__, _factor=None)  # the factor stays where it was made

    def _factorised(self):
        if self._factor is None:
            m = sp.diags(self.mass_dof).tocsc()
            self._factor = factor_definite(self.k - self.sigma * m, points=self.points)
        return self._factor

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """
        ``K^-1 rhs`` with the kept factor of ``K - sigma M`` and iterative refinement.

        Each step shrinks the error by about ``|sigma| / lambda_min``, under 1e-3 on the sheets.
        """
        factor = self._factorised()
        x = factor.solve(rhs)
        for _ in range(REFINEMENT_STEPS):
            x += factor.solve(rhs - self.k @ x)
        return x

    def lowest(self, count: int) -> tuple[np.ndarray, np.ndarray]:
        n = self.mass_dof.size
        m = sp.diags(self.mass_dof).tocsc()
        op = spla.LinearOperator((n, n), matvec=self._factorised().solve, dtype=float)
        try:
            lam, phi = spla.eigsh(self.k, k=count, M=m, sigma=self.sigma, OPinv=op, which='LM',
                                  v0=np.ones(n), tol=1e-12)
        except spla.ArpackError:
            # a cluster of (near) zero modes, a mechanism's, can leave ARPACK's default space of
            # 2 k + 1 vectors without a shift to apply: the space twice that size
            lam, phi = spla.eigsh(self.k, k=count, M=m, sigma=self.sigma, OPinv=op, which='LM',
                                  v0=np.ones(n), tol=1e-12, ncv=min(n, 4 * count + 2))
        order = np.argsort(lam)
        if np.any(order != np.arange(order.size)):
            lam, phi = lam[order], phi[:, order]
        # Renormalise against M (ARPACK's scaling is close, not exact), in place: at this size
        # each copy of the modes is a stage's peak.
        phi /= np.sqrt(np.einsum('ij,i,ij->j', phi, self.mass_dof, phi))
        return lam, phi


#: A worker process's solver (by token), kept with its factor for the next call.
_WORKER_SOLVERS: dict[str, ShiftInvertModes] = {}


def _in_worker(solver: ShiftInvertModes) -> ShiftInvertModes:
    """Return the worker's copy of ``solver`` (factorised by an earlier call, if any)."""
    if solver.token not in _WORKER_SOLVERS:
        _WORKER_SOLVERS.clear()  # one at a time: no factor outlives its use
        _WORKER_SOLVERS[solver.token] = solver
    return _WORKER_SOLVERS[solver.token]


def lowest_modes_in_worker(solver: ShiftInvertModes, count: int
                           ) -> tuple[np.ndarray, np.ndarray]:
    """Run in a :class:`WorkerProcess`: ``solver.lowest(count)``."""
    return _in_worker(solver).lowest(count)


def call_with_solve_in_worker(solver: ShiftInvertModes, function: Callable[..., Any],
                              args: tuple) -> Any:
    """Run in a :class:`WorkerProcess`: ``function(solve, *args)`` with the worker's factor."""
    return function(_in_worker(solver).solve, *args)

"""
Nonlinear spring forces (paper eq. 20) and gravity in generalized coordinates.

For free-DOF displacement ``u = Phi q`` (``Phi`` = the retained modes, or the identity for the
full physical run), measured from the rigidly moving base (see
:mod:`modal_spring_ros.core.motion.anchor_motion`), each spring's vector ``x_j - x_i`` is an affine
function of ``q``:

    delta = delta_rest + G q,     G = D Phi

with ``D`` the sparse spring-difference matrix. The force on the free DOF is ``-D^T`` of the
per-spring force vectors, so its projection on the modes (paper fig. 5, step 4) is
``Q = -G^T f_spring + Phi^T (f_gravity - M 1 a_base(t))``. When the clamp turns, ``u`` is the
displacement in its frame and the loads are the frame's
(:mod:`~modal_spring_ros.core.motion.frame_loads`).

Per step this is one product with ``G``, a few vectorised operations over the springs and one
product with ``G^T``: no Python loop over particles or springs. ``G`` is stored dense when that
is cheap (small scenes, few modes) and applied as ``D`` after ``Phi`` otherwise.
"""
from __future__ import annotations

from modal_spring_ros.core.forces.base import ForceContext, ForceModel, ForceOptions, ForceReport
from modal_spring_ros.core.forces.springs import pull_springs, spring_lengths
from modal_spring_ros.core.motion.frame_loads import FrameLoads
import numpy as np
import scipy.sparse as sp

#: Largest dense ``G`` (entries) kept; beyond it ``G q`` is computed as ``D (Phi q)``.
DENSE_G_LIMIT = 400_000
#: springs per block when the tangent stiffness is summed (bounds its memory)
TANGENT_CHUNK = 4096
#: what the exact model says about itself: nothing to measure, nothing to fall back from
EXACT_REPORT = ForceReport('exact', 'exact every step')


class ExactForces(ForceModel):
    """
    ``Q(q, t)``: total force on the free DOF projected on ``Phi`` (identity when None).

    The paper's method: every spring on every step. The other force models are built on it (it
    is their reference, and where they fall back to).

    :ivar last_max_strain: largest ``|L - l| / l`` over all springs at the last evaluation.
    """

    name = 'exact'

    def __init__(self, model, basis: np.ndarray | None, load_mask: np.ndarray | None = None):
        """
        ``load_mask`` (m, 4), with a basis.

        Which loads (gravity, base acceleration along x, y, z) act on each coordinate (all when
        None).
        """
        s = model.scene
        d = model.dimension
        self.dimension = d
        # The law's pulls f(L) / L are applied by -G^T (eq. 20 pulls i towards j).
        self.law = model.law
        self._l = self.law.rest_length
        rest = model.rest
        self._delta_rest = (rest[s.springs[:, 1]] - rest[s.springs[:, 0]]).T.ravel()
        self._anchors_move = not model.motion.is_static
        self._base_motion = model.motion
        # Loads as one product: [gravity, -M 1_x, -M 1_y, -M 1_z] @ [1, base acceleration (3,)]
        # (-M 1_axis: the inertial load of a unit base acceleration; zero on axes not modelled).
        base_load = np.zeros((model.n_free_dof, 3))
        base_load[:, model.axes] = -(
            model.mass_dof[:, None]
            * (np.arange(model.n_free_dof)[:, None] % d == np.arange(d)[None, :]))
        self._load_coefficients = np.array([1.0, 0.0, 0.0, 0.0])
        d_mat = model.spring_difference
        loads = np.column_stack([model.gravity_force, base_load])
        self._phi = None
        if basis is None:
            self._g, self._gt = d_mat, (-d_mat.T).tocsr()
        else:
            loads = basis.T @ loads
            if d_mat.shape[0] * basis.shape[1] <= DENSE_G_LIMIT:
                dense = np.asarray(d_mat @ basis)
                self._g, self._gt = dense, -np.ascontiguousarray(dense.T)
            else:
                self._phi, self._phit = basis, np.ascontiguousarray(basis.T)
                self._g, self._gt = d_mat, (-d_mat.T).tocsr()
        if load_mask is not None:
            loads = loads * load_mask
        self._load_matrix = np.ascontiguousarray(loads)
        #: the inertial loads of a turning clamp's frame (modal coordinates in that frame)
        self.frame = FrameLoads(model, basis) if model.rotates and basis is not None else None
        self._gravity = self._load_matrix[:, 0].copy()
        self.last_max_strain = 0.0
        # the bending of a flat surface: linear, -B (X + u), exact on any coordinates
        self._bend = self._bend_const = None
        if model.bending_free is not None:
            self._bend, self._bend_const = model.bending_free, model.bending_rest_force.copy()
            if basis is not None:
                self._bend = np.ascontiguousarray(basis.T @ (self._bend @ basis))
                self._bend_const = basis.T @ self._bend_const

    @classmethod
    def build(cls, context: ForceContext, options: ForceOptions) -> 'ExactForces':
        return context.exact

    def report(self) -> ForceReport:
        return EXACT_REPORT

    def spring_deltas(self, q: np.ndarray) -> np.ndarray:
        """(d, E) spring vectors ``x_j - x_i`` for generalized coordinates ``q``."""
        u = q if self._phi is None else self._phi @ q
        delta = self._g @ u
        delta += self._delta_rest
        return delta.reshape(self.dimension, -1)

    def __call__(self, q: np.ndarray, t: float) -> np.ndarray:
        """Total generalized force: springs (eq. 20), bending, and the loads at time ``t``."""
        f = self.elastic_forces(q)
        f += self.loads(t)
        return f

    def elastic_forces(self, q: np.ndarray) -> np.ndarray:
        """Return the springs' generalized force plus the bending's (sets ``last_max_strain``)."""
        return self.add_bending(self.spring_forces(q), q)

    def add_bending(self, force: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Add the bending's generalized force at ``q`` to ``force`` (in place; returned)."""
        if self._bend is not None:
            force -= self._bend @ q
            force += self._bend_const
        return force

    def spring_forces(self, q: np.ndarray) -> np.ndarray:
        """
        Generalized nonlinear spring force ``-G^T f_spring``.

        Generalized nonlinear spring force ``-G^T f_spring`` (sets ``last_max_strain``; see
        :func:`pull_springs`).
        """
        delta = self.spring_force_vectors(q)
        f = self._gt @ delta.ravel()
        if self._phi is not None:
            f = self._phit @ f
        return f

    def spring_force_vectors(self, q: np.ndarray) -> np.ndarray:
        """(d, E) force vectors of the springs at ``q`` (sets ``last_max_strain``)."""
        delta = self.spring_deltas(q)
        self.last_max_strain = pull_springs(delta, self.law)
        return delta

    def loads(self, t: float) -> np.ndarray:
        """
        Generalized gravity and base-excitation load at time ``t`` (linear, exact).

        With a turning clamp, the state-independent loads of its frame (:class:`FrameLoads`).
        """
        if self.frame is not None:
            return self.frame.loads(t)
        if self._anchors_move:
            self._load_coefficients[1:] = self._base_motion.acceleration(t)
            return self._load_matrix @ self._load_coefficients
        return self._gravity.copy()

    def gravity(self) -> np.ndarray:
        """Generalized gravity load alone (no base excitation)."""
        return self._gravity.copy()

    def tangent(self, q: np.ndarray, chunk: int = TANGENT_CHUNK) -> np.ndarray:
        """
        Tangent stiffness ``-dQ_elastic/dq`` at ``q`` (dense, m x m; at rest ``Phi^T K Phi``).

        Per spring the tangent of its pull is the law's ``a I + b n n^T`` (linear spring:
        ``a = k (1 - l/L)``, ``b = k l / L``), ``n = delta / L``; summed over the springs as
        ``sum_c G_c^T diag(a) G_c + H^T diag(b) H`` with ``H = sum_c n_c G_c``, a chunk of
        springs at a time so that ``G`` is never held whole on large scenes.
        """
        delta = self.spring_deltas(q)
        length = spring_lengths(delta)
        a, b = self.law.tangent(length)
        unit = delta / length
        n_springs, d = self._l.size, self.dimension
        m = self._g.shape[1] if self._phi is None else self._phi.shape[1]
        out = np.zeros((m, m))
        for start in range(0, n_springs, chunk):
            stop = min(start + chunk, n_springs)
            g = self._g_rows(start, stop)                      # (d, chunk, m)
            h = np.einsum('dc,dcm->cm', unit[:, start:stop], g)
            for c in range(d):
                out += g[c].T @ (a[start:stop, None] * g[c])
            out += h.T @ (b[start:stop, None] * h)
        if self._bend is not None:
            out += self._bend.toarray() if sp.issparse(self._bend) else self._bend
        return 0.5 * (out + out.T)

    def strain_sensitivity(self, chunk: int = TANGENT_CHUNK) -> float:
        """
        Most any spring's strain can change per unit change of ``q`` (Euclidean norm).

        Spring ``e``'s vector changes by ``G_e dq`` (``G_e``: its d rows of ``G``), so its
        length by at most ``|G_e dq| <= |G_e|_2 |dq|`` and its strain by that over ``l_e``;
        this returns the largest ``|G_e|_2 / l_e`` (spectral norms from the d x d Gram
        matrices ``G_e G_e^T``).
        """
        largest = np.linalg.eigvalsh(self.spring_grams(chunk))[:, -1]
        return float((np.sqrt(np.maximum(largest, 0.0)) * self.law.inv_l).max())

    def _g_rows(self, start: int, stop: int) -> np.ndarray:
        """Rows of ``G`` for springs ``start:stop``, as (d, stop - start, m)."""
        return self.g_rows_of(np.arange(start, stop))

    def spring_grams(self, chunk: int = TANGENT_CHUNK) -> np.ndarray:
        """(E, d, d) ``G_e G_e^T`` of every spring (``G_e``: its d rows of ``G``)."""
        out = np.empty((self._l.size, self.dimension, self.dimension))
        for start in range(0, self._l.size, chunk):
            stop = min(start + chunk, self._l.size)
            g = self._g_rows(start, stop)                      # (d, chunk, m)
            out[start:stop] = np.einsum('acm,bcm->cab', g, g)
        return out

    def g_rows_of(self, springs: np.ndarray) -> np.ndarray:
        """Rows of ``G`` for the springs ``springs``, as (d, len(springs), m)."""
        n_springs, d = self._l.size, self.dimension
        rows = (np.arange(d)[:, None] * n_springs + springs[None, :]).ravel()
        g = self._g[rows]
        if self._phi is not None:
            g = g @ self._phi
        elif sp.issparse(g):
            g = g.toarray()
        return np.asarray(g).reshape(d, springs.size, -1)

    def g_product(self, r: np.ndarray) -> np.ndarray:
        """``G r`` for columns ``r`` (m, S): (d * E, S), component-major rows."""
        return np.asarray(self._g @ (r if self._phi is None else self._phi @ r))

    @property
    def n_springs(self) -> int:
        return int(self._l.size)

    @property
    def rest_deltas(self) -> np.ndarray:
        """(d * E,) spring vectors at rest, component-major."""
        return self._delta_rest

"""
Vibration modes at the rest shape: ``K phi = omega^2 M phi`` on the free DOF (paper eq. 2).

Modes are mass-normalised (``Phi^T M Phi = I``, so the paper's eq. 15 becomes
``q = Phi^T M u``), sorted by frequency, with a deterministic sign.

Small scenes (up to :data:`DENSE_LIMIT` free DOF) get every mode from one dense ``eigh``
(milliseconds for the seed scene). Larger scenes never build a dense ``n x n`` matrix: the
lowest modes are found with shift-invert Lanczos (``eigsh``) on a sparse factorisation that is
kept, and more are computed only when a filter band asks for them.

A singular stiffness on the free DOF (a mechanism) is detected here and reported as a
:class:`~modal_spring_ros.scenes.schema.SceneError` that says how many zero modes there are.
"""
from __future__ import annotations

import time
from typing import Any, Callable

from modal_spring_ros.core.bases.mass_products import mass_gram
from modal_spring_ros.core.bases.shift_invert import (call_with_solve_in_worker,
                                                      lowest_modes_in_worker, ShiftInvertModes)
from modal_spring_ros.core.bases.stored_modes import modes_arrays, modes_key, validated_modes
from modal_spring_ros.core.forces.base import SampleStore
from modal_spring_ros.core.forces.samples import CacheEntryError
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.model.scene import SceneError
from modal_spring_ros.core.worker import WorkerProcess
import numpy as np
import scipy.linalg
import scipy.sparse as sp
import scipy.sparse.linalg as spla

#: Most modes computed on scenes too large for the dense solver, unless asked otherwise.
DEFAULT_MAX_MODES = 256

#: Modes a large scene's basis computes first.
INITIAL_MODES = 32

#: Largest number of free DOF for which every mode is computed with a dense solver.
DENSE_LIMIT = 1000

#: Relative size (against the largest eigenvalue scale) below which an eigenvalue is zero.
ZERO_MODE_RTOL = 1e-9

#: Seed of the generic vector that fixes the modes' signs (see ``_deterministic_signs``).
SIGN_SEED = 20240611

Progress = Callable[[str], None]


def _no_progress(_: str) -> None:
    pass


class ModalBasis:
    """
    The modes of a :class:`MassSpringModel`, computed up to what has been asked for.

    ``worker``: a :class:`~modal_spring_ros.core.worker.WorkerProcess` to run the sparse
    eigensolver in (results are identical), so that computing modes does not hold this
    process's interpreter lock; the node uses one to keep its stream going meanwhile.
    ``samples``: where spring samples trained on this scene's coordinates are kept between runs
    (a :class:`~modal_spring_ros.core.forces.base.SampleStore`; None: trained every run); a
    large scene's modes are kept there too (:mod:`~modal_spring_ros.core.bases.stored_modes`).

    :ivar omega: (m,) circular frequencies (rad/s) of the computed modes, ascending.
    :ivar vectors: (n_free_dof, m) mass-normalised mode shapes.
    :ivar complete: every mode of the scene has been computed.
    """

    def __init__(self, model: MassSpringModel, *, initial_modes: int = INITIAL_MODES,
                 progress: Progress | None = None, dense_limit: int = DENSE_LIMIT,
                 worker: WorkerProcess | None = None, samples: SampleStore | None = None):
        self.model = model
        self.samples = samples
        self.n_dof = model.n_free_dof
        self.progress = progress or _no_progress
        self.dense = self.n_dof <= dense_limit
        self.solve_seconds = 0.0
        #: modes solved for by the sparse eigensolver, summed over its solves (what a planning
        #: budget prices: :func:`~modal_spring_ros.core.auto.budget.modes_work`)
        self.modes_solved = 0
        self.worker = worker
        self._solver: ShiftInvertModes | None = None
        self._cholesky = None  # dense scenes: the factor of K0, made when first needed
        self.omega = np.empty(0)
        self.vectors = np.empty((self.n_dof, 0))
        self.complete = False
        #: the banks of added coordinates built on this basis, by derivative directions
        #: (:func:`~modal_spring_ros.core.simulations.coordinates.shared_bank`)
        self.banks: dict[int, object] = {}
        #: the pair solves of modal derivatives, by their modes, shared by every bank
        #: (:func:`~modal_spring_ros.core.bases.derivatives.added_coordinates`)
        self.pair_solves: dict[bytes, object] = {}
        if self.dense:
            self._compute_dense()
        elif not self._read_stored(min(initial_modes, self.n_dof - 1)):
            self._compute_sparse(min(initial_modes, self.n_dof - 1))

    # -- public --------------------------------------------------------------------------------
    @property
    def count(self) -> int:
        return int(self.omega.size)

    @property
    def frequencies_hz(self) -> np.ndarray:
        return self.omega / (2.0 * np.pi)

    def ensure_count(self, count: int) -> bool:
        """Make at least ``count`` lowest modes available; True when the basis changed."""
        count, solving = min(int(count), self.n_dof), self.to_solve(count)
        if not solving:
            return False
        if count >= self.n_dof - 1:
            # ARPACK cannot return every mode; a scene this size asking for all is a dense job.
            raise ValueError(f'{count} modes requested of a {self.n_dof}-DOF scene: computing '
                             '(nearly) all modes of a large scene is not supported; narrow the '
                             'band or raise modal.max_modes only as far as needed')
        self._compute_sparse(solving)
        return True

    def to_solve(self, count: int) -> int:
        """Return how many modes :meth:`ensure_count` solves for to have ``count`` (0: none)."""
        count = min(int(count), self.n_dof)
        if count <= self.count or self.complete:
            return 0
        return max(count, min(2 * self.count, self.n_dof - 2))

    def ensure_frequency(self, max_hz: float, max_modes: int,
                         affords: Callable[[int], bool] | None = None) -> bool:
        """
        Make every mode up to ``max_hz`` available (at most ``max_modes``).

        ``affords`` (given how many modes the next solve solves for) may stop it before a solve:
        the modes stay what they were, and the caller reads how far they reach. Each solve is
        for twice the modes, or for as many as :meth:`reaching` estimates where that is more
        (a solve is made afresh: reaching in one saves the ones between).
        """
        changed = False
        while (not self.complete and self.frequencies_hz[-1] <= max_hz
               and self.count < min(max_modes, self.n_dof - 2)):
            count = min(max(2 * self.count, self.count + 16, self.reaching(max_hz)), max_modes,
                        self.n_dof - 2)
            if affords is not None and not affords(self.to_solve(count)):
                break
            changed |= self.ensure_count(count)
        return changed

    def reaching(self, max_hz: float) -> int:
        """
        Estimate how many of the lowest modes reach ``max_hz``, a quarter more for safety.

        From how the count grew with frequency over the upper half of the modes there are (a
        power law: as the square of the frequency on a sheet or shell, the cube in a volume);
        0 where there are too few to tell.
        """
        half = self.count // 2
        f = self.frequencies_hz
        if half < 8 or not 0.0 < f[half - 1] < f[-1]:
            return 0
        power = np.log(self.count / half) / np.log(f[-1] / f[half - 1])
        return int(np.ceil(1.25 * self.count * (max_hz / f[-1]) ** power))

    def solve_stiffness(self, rhs: np.ndarray) -> np.ndarray:
        """
        ``K0^-1 rhs`` (columns) with the rest stiffness of the free DOF, in this process.

        A Cholesky factor on dense scenes, the kept sparse LU on large ones (with a worker,
        :meth:`call_with_solve` solves there instead).
        """
        rhs = np.asarray(rhs, dtype=float)
        if rhs.size == 0:
            return rhs.copy()
        if self.dense:
            if self._cholesky is None:
                self._cholesky = scipy.linalg.cho_factor(self.model.stiffness_free.toarray())
            return scipy.linalg.cho_solve(self._cholesky, rhs)
        if self._solver is None:
            self._solver = self._shift_invert()
        return self._solver.solve(rhs)

    def call_with_solve(self, function: Callable[..., Any], *args: Any) -> Any:
        """
        ``function(solve, *args)`` with ``solve(rhs) = K0^-1 rhs``.

        In the worker process on a large scene that has one (so that the caller's interpreter stays
        free for the stream; ``function`` must then be module-level), else here.
        """
        if self.dense or self.worker is None:
            return function(self.solve_stiffness, *args)
        if self._solver is None:
            self._solver = self._shift_invert()
        return self.worker.call(call_with_solve_in_worker, self._solver, function, args)

    def _shift_invert(self) -> ShiftInvertModes:
        return ShiftInvertModes(self.model.stiffness_free, self.model.mass_dof,
                                self.model.free_points)

    def omega_max_estimate(self) -> float:
        """Largest circular frequency of the scene (exact when complete, else a Lanczos value)."""
        if self.complete:
            return float(self.omega[-1])
        if not hasattr(self, '_omega_max'):
            m = self.model.mass_dof
            scale = 1.0 / np.sqrt(m)
            a = sp.diags(scale) @ self.model.stiffness_free @ sp.diags(scale)
            lam = spla.eigsh(a, k=1, which='LA', v0=np.ones(self.n_dof),
                             return_eigenvectors=False, tol=1e-6)
            self._omega_max = float(np.sqrt(max(lam[0], 0.0)))
        return self._omega_max

    # -- solvers -------------------------------------------------------------------------------
    def _compute_dense(self) -> None:
        start = time.perf_counter()
        self.progress(f'computing all {self.n_dof} modes (dense eigh)')
        m = self.model.mass_dof
        inv_sqrt_m = 1.0 / np.sqrt(m)
        k = self.model.stiffness_free.toarray()
        a = inv_sqrt_m[:, None] * k * inv_sqrt_m[None, :]
        lam, psi = scipy.linalg.eigh(a)
        self._check_zero_modes(lam, lam_scale=float(np.max(np.abs(lam))))
        self._store(lam, inv_sqrt_m[:, None] * psi)
        self.complete = True
        self.solve_seconds += time.perf_counter() - start

    def _compute_sparse(self, count: int) -> None:
        start = time.perf_counter()
        if self._solver is None:
            self.progress(f'factorising the {self.n_dof}-DOF stiffness (sparse LU)')
            self._solver = self._shift_invert()
        self.progress(f'computing the {count} lowest modes (shift-invert Lanczos, '
                      f'{self.n_dof} DOF)' + (' in a worker process' if self.worker else ''))
        if self.worker is None:
            lam, phi = self._solver.lowest(count)
        else:
            lam, phi = self.worker.call(lowest_modes_in_worker, self._solver, count)
        self._check_zero_modes(lam, lam_scale=self._solver.lam_scale)
        self._store(lam, phi)
        if self.samples is not None:     # the next run of this scene reads them back
            self.samples.save(modes_key(self.model), modes_arrays(self.omega, self.vectors))
        self.modes_solved += count
        self.solve_seconds += time.perf_counter() - start
        self.progress(f'{count} modes ready: {self.frequencies_hz[0]:.4g} .. '
                      f'{self.frequencies_hz[-1]:.4g} Hz '
                      f'({time.perf_counter() - start:.2f} s)')

    def _read_stored(self, count: int) -> bool:
        """
        Take at least ``count`` lowest modes from the store, checked; True when it had them.

        (:mod:`~modal_spring_ros.core.bases.stored_modes`: an entry that fails its check is
        reported, removed, and the modes are solved for again.)
        """
        if self.samples is None:
            return False
        key = modes_key(self.model)
        try:
            entry = self.samples.load(key)
            if entry is None:
                return False
            omega, vectors = validated_modes(entry, self.model)
        except CacheEntryError as exc:
            self.progress(f'modes cache entry {self.samples.where(key)} refused: {exc}; '
                          'removed, solving again')
            self.samples.discard(key)
            return False
        if omega.size < count:
            return False
        self.omega, self.vectors = omega, vectors
        self.progress(f'{omega.size} modes read from the cache: {self.frequencies_hz[0]:.4g} .. '
                      f'{self.frequencies_hz[-1]:.4g} Hz')
        return True

    def _check_zero_modes(self, lam: np.ndarray, lam_scale: float) -> None:
        zero = int(np.sum(lam <= ZERO_MODE_RTOL * lam_scale))
        if zero:
            more = 'at least ' if (not self.dense and zero == lam.size) else ''
            scene = self.model.scene
            # a cloth or a cable is slack at rest: gravity gives it tension (its loaded shape)
            slack = ('' if np.any(scene.gravity) else
                     ' This scene has no gravity: a cloth or a cable (flat or straight at rest, '
                     'nothing resists moving out of its plane or line) is stiff only once it '
                     'hangs; give it gravity (e.g. gravity: [0, 0, -9.81]) and it is taken about '
                     'the shape it hangs in, or give a cloth material.bending.')
            raise SceneError(
                f"scene '{scene.name}': the stiffness is singular on the free DOF: "
                f'{more}{zero} zero-stiffness mode(s) (a mechanism). Add shear (diagonal) '
                f'springs, bending springs for out-of-plane motion, or fix more '
                f'particles.{slack}')

    def _store(self, lam: np.ndarray, phi: np.ndarray) -> None:
        phi = _deterministic_signs(phi, self.model.mass_dof)
        if self.count:
            # The basis grows: the modes already handed out stay exactly as they were (a run's
            # state is carried over by mode index; a mode coming back with another sign, or
            # another member of a degenerate pair, would move the object).
            lam, phi = _grown(self.omega ** 2, self.vectors, lam, phi, self.model.mass_dof)
        self.vectors = np.ascontiguousarray(phi)
        self.omega = np.sqrt(np.maximum(lam, 0.0))


def _deterministic_signs(phi: np.ndarray, mass: np.ndarray) -> np.ndarray:
    """
    Fix each mode's sign in ``phi`` (in place, and return it) by a rule the solver cannot sway.

    A mode's sign is that of its projection ``phi^T M w`` on a fixed generic vector ``w``
    (seeded): unlike "the largest component is positive", which picks either sign when a mode
    has two components of equal size and opposite sign (every symmetric mode of a symmetric
    scene), it is tied only on a set of measure zero; a projection too small to trust falls
    back to the largest component.
    """
    if phi.size == 0:
        return phi
    generic = np.random.default_rng(SIGN_SEED).uniform(0.5, 1.5, phi.shape[0])
    projection = phi.T @ (mass * generic)
    scale = np.sqrt(np.einsum('ij,i,ij->j', phi, mass, phi)) * np.linalg.norm(mass * generic)
    pivot = np.argmax(np.abs(phi), axis=0)
    fallback = phi[pivot, np.arange(phi.shape[1])]
    signs = np.where(np.abs(projection) > 1e-6 * scale, np.sign(projection), np.sign(fallback))
    signs[signs == 0] = 1.0
    phi *= signs  # in place: the caller's fresh modes
    return phi


def _grown(old_lam: np.ndarray, old_phi: np.ndarray, lam: np.ndarray, phi: np.ndarray,
           mass: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the modes ``old`` extended by those of ``lam, phi`` beyond them.

    ``lam, phi`` are a fresh computation of more of the lowest modes. Its first modes repeat
    ``old`` up to sign and, within a degenerate group, up to a rotation; ``old`` is kept as it
    is, and the fresh modes past it are made M-orthogonal to it (which, for a degenerate pair cut
    by the old count, leaves the partner of the kept member) and M-normalised again.
    """
    k = old_lam.size
    if lam.size <= k:
        return old_lam, old_phi
    extra = phi[:, k:]
    extra = extra - old_phi @ (old_phi.T @ (mass[:, None] * extra))
    value, vector = np.linalg.eigh(mass_gram(extra, mass))
    if value.min() <= 1e-12 * max(value.max(), 1e-300):
        raise RuntimeError('the new modes repeat the ones already computed (eigensolver '
                           'returned a dependent set)')
    # Loewdin orthonormalisation: the M-orthonormal set nearest to the fresh modes (signs kept).
    extra = extra @ (vector @ np.diag(value ** -0.5) @ vector.T)
    return np.concatenate([old_lam, lam[k:]]), np.concatenate([old_phi, extra], axis=1)

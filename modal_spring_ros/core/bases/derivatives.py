"""
Modal derivatives with static load vectors.

The band's second-order response (Barbic and James 2005), added to the kept rest modes as a fixed
basis per band.

Rest modes describe the motion only while the springs barely rotate. A sheet swaying in its
first mode rotates its vertical springs and shortens; written in rest modes that sway stretches
them instead, so its stiffness, its resonance and its phase drift. The shortening is the
second-order, quasi-static response of the kept modes, and it lies in stiff modes far above the
band. The modal derivative of kept modes ``i <= j``,

    K0 psi_ij = -(dK/dq_j) phi_i,

is that response's direction. A band's added coordinates are built once per band:

1. every ``psi_ij`` over the kept modes (the pairs of the lowest :data:`MAX_PAIR_MODES`),
2. with their components on the kept modes and on every rest mode the band removes below its
   top taken out, so that a band-pass never puts motion back into the modes it removes,
3. weighted by ``omega_1^2 / (omega_i omega_j)`` times the two modes' dynamic amplification at
   the clamp's driving frequencies (:func:`drive_gains`: about ``1 / (2 h)`` for a mode the
   clamp shakes at resonance, 1 for one it drives quasi-statically) and reduced to the leading
   ``directions`` mass-PCA directions: the pairs the motion excites most lead. (Without the
   gains a band of more modes added pairs of modes the clamp barely moves, and a resonance's
   own ``psi_11`` fell out of the leading directions: on ``sheet_32x32_resonance`` 16, 24 and
   32 modes were 1.3, 2.1 and 4.4 % off over 6 s, with them 0.35-0.42 %.)
4. with the static load vectors ``K0^-1 f_gravity`` and ``K0^-1 M 1_axis`` (each axis the base
   moves along), and for a turning clamp those of its frame's load patterns (gravity turned,
   centrifugal and Euler loads), projected the same way, each only when the load varies at
   frequencies within the band's span (a quasi-static response moves at its load's
   frequencies),
5. mass-orthonormalised and rotated so that ``K0`` is diagonal on them: each added coordinate
   has an ``omega`` of its own, and the modal damping, the diagonal operators and both
   integrators carry over unchanged. The forces stay exact (eq. 20 in physical space).

The pair solves (step 1 with its weights: the cost, a sparse solve per pair) depend on the pair
modes alone, so two bands of the same lowest modes share them (a plan and its richer sibling:
more modes, more directions): they are kept on the basis (:attr:`ModalBasis.pair_solves`)
where they are solved in this process and take at most ``PAIR_SOLVES_BYTES``.

The band keeps its meaning: the added coordinates move with what the kept modes drive (the
springs' second-order response) and with the loads in the band, not with a load outside it (a
base shaken at 8 Hz does not drive them in a low-pass below 8 Hz: their share of that load is
left out, as it is of the static vectors).
"""
from __future__ import annotations

import dataclasses
import time

from modal_spring_ros.core.bases.basis import ModalBasis, Progress
from modal_spring_ros.core.bases.mass_products import mass_gram
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.motion.frame_loads import frame_load_patterns
import numpy as np

#: Default number of mass-PCA derivative directions added to a band.
DEFAULT_DIRECTIONS = 15
#: Pairs are formed among the band's lowest this many modes (their weight falls as
#: ``1 / (omega_i omega_j)``: the 24th mode's pairs weigh about 1/100 of the first's on the sheets;
#: a 256-mode band would otherwise need 32,896 solves).
MAX_PAIR_MODES = 24
#: Most pairs whose right-hand sides are built and solved at once.
PAIR_CHUNK = 64
#: Bytes one chunk's per-spring arrays (about ``PER_SPRING_ARRAYS`` arrays of d x E x chunk
#: floats at once) may take: fewer pairs a chunk on scenes with many springs.
CHUNK_BYTES = 16 * 2**20
#: Arrays of d x E x chunk floats :func:`_per_spring` holds at once at its peak.
PER_SPRING_ARRAYS = 8
#: The most a mode's dynamic amplification weighs a pair by (an undamped mode driven exactly at
#: its frequency would weigh without bound).
MAX_DRIVE_GAIN = 100.0
#: Directions whose mass norm falls below this share of the largest are dependent: dropped.
DEPENDENT_RTOL = 1e-10
#: A static response with less than this share of it outside the band's modes adds nothing.
REMAINDER_RTOL = 1e-8
#: The most a basis keeps of one set of pair solves (a 10k-particle sheet's 300 pairs: 48 MB).
PAIR_SOLVES_BYTES = 64 * 2**20


@dataclasses.dataclass(frozen=True)
class PairSolves:
    """The weighted solves of every pair of a set of modes (``phi``: their shapes, as solved)."""

    phi: np.ndarray
    solved: np.ndarray      # (n_free_dof, pairs): weighted, before the band's projection
    scale: float            # the largest mass norm among them


@dataclasses.dataclass(frozen=True)
class AddedCoordinates:
    """The coordinates a band adds to its kept rest modes."""

    vectors: np.ndarray     # (n_free_dof, r), mass-orthonormal, M-orthogonal to the rest modes
    omega: np.ndarray       # (r,) sqrt of K0 on each (K0 is diagonal on them), rad/s
    derivative_count: int   # how many of them are derivative directions (the rest: static)
    seconds: float          # time to compute them
    loads: np.ndarray       # (4,) bool: the loads (gravity, base x, y, z) that act on them

    @property
    def count(self) -> int:
        return int(self.omega.size)


def tangent_derivative(model: MassSpringModel, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """
    ``(dK/du along b) a`` at the reference shape (at rest, or the loaded shape).

    For free-DOF displacement fields ``a`` and ``b`` given as columns (n_free_dof, P): the change
    of the springs' tangent stiffness applied to ``a`` per unit displacement along ``b``, from
    the springs' law (:meth:`~modal_spring_ros.core.laws.SpringLaw.derivative_terms`).
    """
    d, lengths, terms, unit, diff = _spring_geometry(model)
    n_springs = lengths.size
    alpha = np.asarray(diff @ a).reshape(d, n_springs, -1)   # (d, E, P) spring differences
    beta = np.asarray(diff @ b).reshape(d, n_springs, -1)
    per_spring = _per_spring(alpha, beta, unit, lengths, terms)
    return np.asarray(diff.T @ per_spring.reshape(d * n_springs, -1))


def _per_spring(alpha: np.ndarray, beta: np.ndarray, unit: np.ndarray, lengths: np.ndarray,
                terms: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """
    (d, E, P) per-spring vectors of the tangent derivative (see :func:`tangent_derivative`).

    From the springs' differences ``alpha`` of ``a`` and ``beta`` of ``b`` and the law's
    ``(f'', b)`` at the reference lengths: ``f'' (n.beta)(n.alpha) n + (b / L)(n.beta)(alpha -
    n (n.alpha)) + b (n' (n.alpha) + n (n'.alpha))``, ``n' = (beta - n (n.beta)) / L``.
    """
    curvature, along = terms
    n = unit[:, :, None]
    n_beta = (n * beta).sum(axis=0)                 # (E, P)
    n_alpha = (n * alpha).sum(axis=0)
    inv_l = (1.0 / lengths)[:, None]
    n_prime = (beta - n * n_beta) * inv_l
    out = along[:, None] * (
        n_beta * inv_l * (alpha - n * n_alpha)
        + n_prime * n_alpha
        + n * (n_prime * alpha).sum(axis=0))
    if np.any(curvature):                           # zero for the linear spring
        out += n * (curvature[:, None] * n_beta * n_alpha)
    return out


def _spring_geometry(model: MassSpringModel):
    """
    Dimension, lengths ``L``, the law's ``(f'', b)``, unit vectors (d, E), and ``D``.

    All at the reference shape (at rest ``L = l``; about a loaded shape, the stretched lengths).
    """
    rest = model.rest
    springs = model.scene.springs
    delta = (rest[springs[:, 1]] - rest[springs[:, 0]]).T
    lengths = np.sqrt(np.einsum('de,de->e', delta, delta))
    return (model.dimension, lengths, model.law.derivative_terms(lengths), delta / lengths,
            model.spring_difference)


def loads_in_band(model: MassSpringModel, low_hz: float = 0.0,
                  high_hz: float = np.inf) -> np.ndarray:
    """
    Which loads vary only at frequencies within ``low_hz .. high_hz``.

    As a mask over (gravity, base acceleration along x, y, z): gravity is constant (0 Hz), a base
    axis moves at its anchor motion's frequencies. A load the scene does not have is never in band.
    """
    mask = np.zeros(4, dtype=bool)
    mask[0] = bool(np.any(model.gravity_force != 0.0)) and low_hz <= 0.0
    drives: dict[int, list[float]] = {}
    for c in model.motion.components:
        if c.amplitude != 0.0 and c.axis in model.axes:
            drives.setdefault(c.axis, []).append(c.frequency_hz)
    for axis, f in drives.items():
        mask[1 + axis] = low_hz <= min(f) and max(f) <= high_hz
    return mask


def static_load_vectors(model: MassSpringModel, low_hz: float = 0.0,
                        high_hz: float = np.inf) -> np.ndarray:
    """
    (n_free_dof, s) loads whose static response is added.

    Gravity, and the inertial load ``M 1_axis`` of each axis the base moves along, each only when
    it is in band (:func:`loads_in_band`): the quasi-static response to a load moves at the load's
    frequencies, so a load outside the band would put them back in.
    """
    mask = loads_in_band(model, low_hz, high_hz)
    loads = [model.gravity_force] if mask[0] else []
    d = model.dimension
    for slot, axis in enumerate(model.axes):
        if mask[1 + axis]:
            load = np.zeros(model.n_free_dof)
            load[slot::d] = model.mass_dof[slot::d]
            loads.append(load)
    if model.rotates and _turns_in_band(model, low_hz, high_hz):
        loads.extend(frame_load_patterns(model))
    return np.column_stack(loads) if loads else np.empty((model.n_free_dof, 0))


def _turns_in_band(model: MassSpringModel, low_hz: float, high_hz: float) -> bool:
    """Tell whether the clamp turns only at frequencies within ``low_hz .. high_hz``."""
    f = model.motion.rotation_frequencies_hz
    return bool(f.size) and low_hz <= float(f.min()) and float(f.max()) <= high_hz


def added_coordinates(basis: ModalBasis, keep: np.ndarray,
                      directions: int = DEFAULT_DIRECTIONS,
                      progress: Progress | None = None) -> AddedCoordinates:
    """
    Return the coordinates a band keeping rest modes ``keep`` adds (see the module text).

    Modes ``0 .. max(keep)`` must be computed. Empty when the band keeps every mode of the
    scene (nothing is left to add). On a large scene with a worker process it is computed
    there (the pair solves use the sparse factor kept in it).
    """
    start = time.perf_counter()
    keep = np.asarray(keep, dtype=np.int64)
    if basis.complete and keep.size == basis.count:  # every mode: nothing left to add
        return AddedCoordinates(np.empty((basis.n_dof, 0)), np.empty(0), 0, 0.0,
                                np.zeros(4, dtype=bool))
    pair_modes = keep[:MAX_PAIR_MODES]
    pairs = pair_modes.size * (pair_modes.size + 1) // 2
    solves = kept_pair_solves(basis, pair_modes)
    if progress is not None and pair_modes.size:
        progress(f'modal derivatives: {pairs} pairs of {pair_modes.size} modes'
                 + (' (their solves kept from another band)' if solves is not None
                    else ' in a worker process' if basis.worker and not basis.dense else ''))
    in_process = basis.dense or basis.worker is None
    if (solves is None and in_process and pair_modes.size
            and basis.n_dof * pairs * 8 <= PAIR_SOLVES_BYTES):
        phi = basis.vectors[:, pair_modes]
        solves = PairSolves(phi.copy(), *pair_solutions(
            basis.solve_stiffness, basis.model, phi, basis.omega[pair_modes]))
        basis.pair_solves[pair_modes.tobytes()] = solves
    # the band's span: from 0 Hz when it keeps the lowest mode, else from its lowest mode
    f = basis.frequencies_hz
    span = (0.0 if keep[0] == 0 else float(f[keep[0]]), float(f[keep[-1]]))
    vectors, omega2, count = basis.call_with_solve(
        _compute, basis.model, basis.vectors[:, :int(keep.max()) + 1],
        basis.vectors[:, pair_modes], basis.omega[pair_modes], span, directions,
        None if solves is None else (solves.solved, solves.scale))
    return AddedCoordinates(vectors, np.sqrt(np.maximum(omega2, 0.0)), count,
                            time.perf_counter() - start, loads_in_band(basis.model, *span))


def kept_pair_solves(basis: ModalBasis, modes: np.ndarray) -> PairSolves | None:
    """Return the pair solves of ``modes`` kept on ``basis``, where their shapes are unchanged."""
    kept = basis.pair_solves.get(modes.tobytes())
    if kept is None or not np.array_equal(kept.phi, basis.vectors[:, modes]):
        return None
    return kept


def _compute(solve, model: MassSpringModel, below: np.ndarray, phi: np.ndarray,
             omega: np.ndarray, span: tuple[float, float], directions: int,
             solved: tuple[np.ndarray, float] | None = None
             ) -> tuple[np.ndarray, np.ndarray, int]:
    """
    Return the added vectors.

    Their ``omega^2`` and how many are derivative directions, given ``solve(rhs) = K0^-1 rhs``, the
    modes ``below`` to project out, and the pair modes (their weighted solves where ``solved``
    holds them, with their largest mass norm).
    """
    mass = model.mass_dof

    def project(x: np.ndarray) -> np.ndarray:
        return x - below @ (below.T @ (mass[:, None] * x))

    if solved is None:
        solved_all, scale = pair_solutions(solve, model, phi, omega, project)
    else:       # projected in the chunks they were solved in: the same vectors either way
        step = pair_chunk(model.dimension, model.scene.n_springs)
        solved_all, scale = np.empty_like(solved[0]), solved[1]
        for first in range(0, solved_all.shape[1], step):
            solved_all[:, first:first + step] = project(
                np.ascontiguousarray(solved[0][:, first:first + step]))
    derivatives = _leading_directions(solved_all, mass, directions, REMAINDER_RTOL * scale) \
        if solved_all.shape[1] else np.empty((model.n_free_dof, 0))
    del solved_all
    loads = static_load_vectors(model, *span)
    static = _remainders(solve(loads) if loads.size else loads, mass, project)
    vectors, omega2 = _orthonormal_diagonal(np.column_stack([derivatives, static]), mass,
                                            model, project)
    return vectors, omega2, min(derivatives.shape[1], vectors.shape[1])


def pair_solutions(solve, model: MassSpringModel, phi: np.ndarray, omega: np.ndarray,
                   project=None) -> tuple[np.ndarray, float]:
    """
    Return the weighted solves ``psi_ij`` of every pair of modes ``phi``, and their largest norm.

    Each projected by ``project`` as its chunk is solved where given (no second array of them
    all is held).
    """
    mass = model.mass_dof
    m = omega.size
    pairs = np.array([(i, j) for i in range(m) for j in range(i, m)],
                     dtype=np.int64).reshape(-1, 2)
    d, lengths, terms, unit, diff = _spring_geometry(model)
    g = np.asarray(diff @ phi).reshape(d, lengths.size, -1)
    gain = drive_gains(model, omega)
    weights = (omega[0] ** 2 * gain[pairs[:, 0]] * gain[pairs[:, 1]]
               / (omega[pairs[:, 0]] * omega[pairs[:, 1]])) if pairs.size else []
    solved_all = np.empty((model.n_free_dof, len(pairs)))  # filled chunk by chunk, not stacked
    scale = 0.0
    step = pair_chunk(d, lengths.size)
    for first in range(0, len(pairs), step):
        chunk = pairs[first:first + step]
        per_spring = _per_spring(g[:, :, chunk[:, 0]], g[:, :, chunk[:, 1]], unit, lengths,
                                 terms)
        rhs = -(diff.T @ per_spring.reshape(d * lengths.size, -1))
        del per_spring
        solved = solve(rhs) * weights[first:first + step]
        scale = max(scale, float(np.sqrt(np.einsum('ij,i,ij->j', solved, mass, solved).max())))
        solved_all[:, first:first + step] = solved if project is None else project(solved)
    return solved_all, scale


def drive_gains(model: MassSpringModel, omega: np.ndarray) -> np.ndarray:
    """
    Return each mode's dynamic amplification at the clamp's driving frequencies, at least 1.

    ``omega_i^2 / |omega_i^2 - Omega^2 + i C_i Omega|`` (the scene's modal damping ``C_i``) at
    the worst of the clamp's frequencies ``Omega`` (a followed pose: up to its filter's
    bandwidth), capped at :data:`MAX_DRIVE_GAIN`; 1 where the clamp does not move.
    """
    omega = np.asarray(omega, dtype=float)
    damping = model.scene.damping.modal_coefficients(omega)
    gain = np.ones(omega.size)
    for drive in 2.0 * np.pi * np.asarray(model.motion.frequencies_hz, float):
        response = np.abs(omega ** 2 - drive ** 2 + 1j * damping * drive)
        gain = np.maximum(gain, omega ** 2 / np.maximum(response, omega ** 2 / MAX_DRIVE_GAIN))
    return gain


def pair_chunk(dimension: int, springs: int) -> int:
    """Return how many pairs a chunk takes: up to ``PAIR_CHUNK``, within ``CHUNK_BYTES``."""
    per_pair = PER_SPRING_ARRAYS * dimension * springs * 8
    return int(min(PAIR_CHUNK, max(1, CHUNK_BYTES // max(per_pair, 1))))


def _leading_directions(x: np.ndarray, mass: np.ndarray, count: int, floor: float
                        ) -> np.ndarray:
    """
    Return the ``count`` leading mass-PCA directions of the columns of ``x`` (mass-orthonormal).

    Of those whose singular value passes ``floor`` (below it, what is left after the projection is
    round-off).
    """
    value, vector = np.linalg.eigh(mass_gram(x, mass))  # the SVD's right side, from the Gram
    order = np.argsort(value)[::-1]
    value, vector = value[order], vector[:, order]
    keep = min(count, int(np.sum(value > max(DEPENDENT_RTOL ** 2 * max(value[0], 0.0),
                                             floor ** 2))))
    return (x @ vector[:, :keep]) / np.sqrt(value[:keep])


def _remainders(x: np.ndarray, mass: np.ndarray, project) -> np.ndarray:
    """
    Return the parts of the columns of ``x`` outside the projected modes, each of unit mass norm.

    A column with (almost) nothing outside them is dropped.
    """
    before = np.sqrt(np.einsum('ij,i,ij->j', x, mass, x))
    x = project(x)
    after = np.sqrt(np.einsum('ij,i,ij->j', x, mass, x))
    keep = after > REMAINDER_RTOL * before
    return x[:, keep] / after[keep]


def _orthonormal_diagonal(x: np.ndarray, mass: np.ndarray, model: MassSpringModel, project
                          ) -> tuple[np.ndarray, np.ndarray]:
    """
    Mass-orthonormalise the columns of ``x`` (dropping dependent ones).

    Then rotate them so that ``K0`` is diagonal on them; returns the vectors and ``omega^2``,
    ascending.
    """
    if x.shape[1] == 0:
        return x, np.empty(0)
    value, vector = np.linalg.eigh(mass_gram(x, mass))
    independent = value > DEPENDENT_RTOL * value.max()
    x = project(x @ (vector[:, independent] / np.sqrt(value[independent])))
    stiffness = x.T @ (model.stiffness_free @ x)
    omega2, rotation = np.linalg.eigh(0.5 * (stiffness + stiffness.T))
    return np.ascontiguousarray(x @ rotation), omega2

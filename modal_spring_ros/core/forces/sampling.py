"""
Energy-conserving sampling and weighting of the springs (ECSW; Farhat et al.

2014, the cubature of An, Kim and James 2008).

The generalized spring force is a sum over the springs, ``Q(q) = sum_e Q_e(q)`` with
``Q_e = -G_e^T f_e``. It is approximated by a weighted sum over a small sample of them,
``Q(q) ~ sum_{e in S} w_e Q_e(q)``, with every weight non-negative: the reduced force is then
still the gradient of a (weighted) spring energy, so an undamped run conserves it and the
explicit step stays stable, which signed least-squares weights do not give.

Training: on snapshots ``q_s`` of the kept coordinates (see :func:`training_snapshots`), the
weights solve the non-negative least-squares problem ``min |A w - b|``, ``w >= 0``, where the
column of spring ``e`` stacks its contributions ``Q_e(q_s)`` over the snapshots (each snapshot
scaled by its total force, so that every one counts by its relative error) and ``b`` stacks
the totals. It is solved greedily: springs drawn from those whose contributions correlate most
with what is still missing join the sample in batches, the weights of the sample are solved with
``scipy.optimize.nnls``, springs whose weight drops to zero leave, until the training error is
below the tolerance. ``A`` is never built whole: its product with the residual is one product
with ``G`` per chunk of snapshots.
"""
from __future__ import annotations

import dataclasses
import math
import time
from typing import Callable

from modal_spring_ros.core.threads import stepping_threads
import numpy as np
import scipy.optimize

#: Default largest relative error of the sampled force on the training snapshots.
DEFAULT_TOLERANCE = 0.01
#: Springs tried beside the sample each round (most leave again with a zero weight), drawn at
#: random from the ``SPREAD`` times as many springs most correlated with what the sample still
#: misses: the most correlated few are neighbours doing the same work, of which the weights
#: keep one, so a spread pool needs a quarter of the rounds on a fine sheet.
POOL = 400
SPREAD = 10
#: Most greedy rounds.
MAX_ROUNDS = 200
#: Snapshots whose products with ``G`` are held at once: the correlation with the residual is
#: summed over chunks of this many, so that training holds its snapshots' per-spring forces and
#: one chunk's products, not a second and third array as large as the forces.
SNAPSHOT_CHUNK = 8
#: A sample that needs this share of the springs and still misses the tolerance cannot pay (it
#: would cost about as much as every spring): training gives up and says so.
MAX_SAMPLE_SHARE = 0.9


@dataclasses.dataclass(frozen=True)
class SpringSample:
    """The sampled springs and their weights."""

    springs: np.ndarray        # (k,) spring indices
    weights: np.ndarray        # (k,) non-negative weights
    training_error: float      # relative force error on the training snapshots
    held_out_error: float      # relative force error on snapshots not trained on
    seconds: float             # time to train
    gave_up: str = ''          # why training stopped without a sample worth using, if it did

    @property
    def count(self) -> int:
        return int(self.springs.size)


def _g_times(forces, r: np.ndarray) -> np.ndarray:
    """``G r`` for columns ``r`` (m, S), as (S, d, E)."""
    return forces.g_product(r).T.reshape(-1, forces.dimension, forces.n_springs)


def _correlation(forces, per_spring: np.ndarray, residual: np.ndarray) -> np.ndarray:
    """Return ``-sum_s f_e(q_s) . (G r_s)_e`` for every spring ``e`` (E,), a chunk at a time."""
    count = per_spring.shape[0]
    r = residual.reshape(count, -1)
    total = np.zeros(per_spring.shape[2])
    for start in range(0, count, SNAPSHOT_CHUNK):
        chunk = slice(start, start + SNAPSHOT_CHUNK)
        total -= np.einsum('sde,sde->e', per_spring[chunk], _g_times(forces, r[chunk].T))
    return total


def _per_spring_forces(forces, snapshots: np.ndarray) -> np.ndarray:
    """(S, d, E) each spring's force vector on each snapshot, written into one array."""
    first = forces.spring_force_vectors(snapshots[0])
    out = np.empty((len(snapshots),) + first.shape)
    out[0] = first
    for s in range(1, len(snapshots)):
        out[s] = forces.spring_force_vectors(snapshots[s])
    return out


def _columns(forces, per_spring: np.ndarray, springs: np.ndarray) -> np.ndarray:
    """(S * m, k) contributions ``Q_e(q_s)`` of ``springs``, stacked over the snapshots."""
    g = forces.g_rows_of(springs)                                  # (d, k, m)
    q_e = -np.einsum('dkm,sdk->smk', g, per_spring[:, :, springs])
    return q_e.reshape(-1, springs.size)


def relative_error(forces, sample: SpringSample, snapshots: np.ndarray) -> float:
    """Largest relative error of the sampled spring force over ``snapshots`` (S, m)."""
    worst = 0.0
    for q in snapshots:
        exact = forces.spring_forces(q)
        per_spring = forces.spring_force_vectors(q)[None]
        sampled = _columns(forces, per_spring, sample.springs) @ sample.weights
        worst = max(worst, float(np.linalg.norm(sampled - exact))
                    / max(float(np.linalg.norm(exact)), 1e-300))
    return worst


@stepping_threads()
def train(forces, snapshots: np.ndarray, held_out: np.ndarray,
          tolerance: float = DEFAULT_TOLERANCE,
          progress: Callable[[str], None] | None = None) -> SpringSample:
    """
    Find the springs and non-negative weights that reproduce the spring force.

    The springs and non-negative weights that reproduce the spring force of ``forces`` (a
    :class:`~modal_spring_ros.core.forces.exact.ExactForces`) on ``snapshots`` (S, m) within
    ``tolerance`` (relative, each snapshot), checked on ``held_out``.
    """
    start = time.perf_counter()
    per_spring = _per_spring_forces(forces, snapshots)                          # (S, d, E)
    totals = np.stack([forces.spring_forces(q) for q in snapshots])             # (S, m)
    scale = 1.0 / np.maximum(np.linalg.norm(totals, axis=1), 1e-300)            # per snapshot
    b = (totals * scale[:, None]).ravel()
    per_spring *= scale[:, None, None]
    n_springs = per_spring.shape[2]
    # each column's norm: sum_s f_e(q_s)^T (G_e G_e^T) f_e(q_s), from the d x d Gram per spring
    gram = forces.spring_grams()                                                # (E, d, d)
    norms = np.sqrt(np.maximum(np.einsum('sde,edf,sfe->e', per_spring, gram, per_spring),
                               1e-300))
    chosen = np.empty(0, dtype=np.int64)        # the sample: springs of non-zero weight
    weights = np.empty(0)
    residual = b.copy()
    error = 1.0
    rng = np.random.default_rng(0)
    for rounds in range(1, MAX_ROUNDS + 1):
        # correlation of each spring's column with the residual, over its norm:
        # -sum_s f_e(q_s) . (G r_s)_e / |A_e|
        correlation = _correlation(forces, per_spring, residual) / norms
        correlation[chosen] = -np.inf
        top = min(SPREAD * POOL, n_springs - chosen.size)
        best = np.argpartition(-correlation, top - 1)[:top] if top > 0 else chosen[:0]
        best = best[correlation[best] > 0.0]
        if best.size > POOL:  # seeded: the same springs train the same sample
            best = rng.choice(best, POOL, replace=False)
        if best.size == 0:
            break
        candidates = np.concatenate([chosen, best])
        columns = _columns(forces, per_spring, candidates)
        w, _ = scipy.optimize.nnls(columns, b, maxiter=50 * candidates.size)
        keep = w > 0.0
        chosen, weights = candidates[keep], w[keep]
        residual = b - columns[:, keep] @ weights
        error = float(np.max(np.linalg.norm(residual.reshape(len(snapshots), -1), axis=1)))
        if progress is not None:
            progress(f'sampling springs: {chosen.size} of {n_springs}, training error '
                     f'{error:.2%}')
        if error <= tolerance:
            break
        if chosen.size >= MAX_SAMPLE_SHARE * n_springs:
            why = (f'sampling cannot pay here: {chosen.size} of {n_springs} springs still miss '
                   f'{tolerance:.2%} (training error {error:.2%})')
            if progress is not None:
                progress(why)
            return SpringSample(np.sort(chosen), weights[np.argsort(chosen)], error, math.nan,
                                time.perf_counter() - start, gave_up=why)
    keep = weights > 0.0                     # a spring whose weight fell to zero is not sampled
    order = np.argsort(chosen[keep])
    sample = SpringSample(chosen[keep][order], weights[keep][order], error, math.nan, 0.0)
    held = relative_error(forces, sample, held_out) if len(held_out) else math.nan
    return dataclasses.replace(sample, held_out_error=held,
                               seconds=time.perf_counter() - start)

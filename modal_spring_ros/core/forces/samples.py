"""
Where a spring sample comes from: the scene's own motion, trained, kept in a store.

A sample is trained per set of coordinates from snapshots of the scene's own motion
(:func:`training_snapshots`) and kept in a :class:`SampleStore`, keyed by a hash of the springs,
the coordinates and the tolerance (:func:`sample_key`), so that a restart does not train again.
The store is a front end's (files in a cache folder: :mod:`modal_spring_ros.runs.sample_cache`);
the core reads and writes nothing itself. What a store gives back is input: every entry is
validated (:func:`validated_sample`) before it is used, and a bad one is reported, discarded and
trained again.
"""
from __future__ import annotations

import dataclasses
import hashlib
import math
import time
from typing import Callable, Mapping

from modal_spring_ros.core.forces.base import SampleStore
from modal_spring_ros.core.forces.exact import ExactForces
from modal_spring_ros.core.forces.sampling import relative_error, SpringSample, train
from modal_spring_ros.core.integrators import DiagonalOperators, integrator, stable_step
from modal_spring_ros.core.worker import WorkerProcess
import numpy as np

#: the sample is trained to this share of the tolerance, so that states it was not trained
#: on stay within the tolerance
TRAINING_SHARE = 0.3
#: the exact run the snapshots are taken from: at most this long, s, and this many steps,
#: and the snapshots taken from it; its step resolves the fastest coordinate's period in this
#: many steps (no finer than the run's own step: a snapshot needs the motion, not the
#: stream's accuracy, and every step evaluates every spring)
TRAINING_STEPS_PER_PERIOD = 10
TRAINING_RUN_S = 2.0
TRAINING_STEPS = 6000
RUN_SNAPSHOTS = 80
#: random states around the run's, as a share of the snapshots, and their spread (in the
#: run's standard deviations)
RANDOM_SHARE = 0.5
RANDOM_SPREAD = 1.5
#: an entry's force error is recomputed on this many states when it is loaded, and must be
#: what it was when the sample was stored (to this relative round-off), or within
#: CHECK_FACTOR times the tolerance (an entry stored without it; the states are not the ones
#: it was trained on, so a valid sample may be further off on them)
CHECK_STATES, CHECK_FACTOR, CHECK_ROUND_OFF = 4, 3.0, 1e-6


class CacheEntryError(ValueError):
    """A stored sample that cannot be used; the message says why."""


def training_snapshots(exact: ExactForces, omega2: np.ndarray, damping: np.ndarray,
                       dt: float, seed: int = 0, progress: Callable[[str], None] | None = None
                       ) -> tuple[np.ndarray, np.ndarray]:
    """
    (training, held-out) snapshots of the coordinates.

    A short exact run from rest (the scene released under its loads), alternately, and random
    states around it. ``progress`` hears how far the run is, a tenth at a time (on a large
    scene it is the longest part of training).
    """
    fastest = math.sqrt(max(float(omega2.max()), 1e-300))
    dt = max(dt, min(2.0 * math.pi / fastest / TRAINING_STEPS_PER_PERIOD,
                     TRAINING_RUN_S / RUN_SNAPSHOTS))
    ops = DiagonalOperators(1.0, damping, omega2, dt)
    stepper = integrator('explicit' if dt < stable_step('explicit', fastest) else 'average')
    steps = max(min(int(round(TRAINING_RUN_S / dt)), TRAINING_STEPS), RUN_SNAPSHOTS)
    every = max(steps // RUN_SNAPSHOTS, 1)
    tenth = max(steps // 10, 1)
    q = v = np.zeros(omega2.size)
    a = exact(q, 0.0) - damping * v
    run = []
    for k in range(1, steps + 1):
        t = k * dt
        q, v, a, _ = stepper.step(q, v, a, dt, lambda x: exact(x, t), ops)
        if k % every == 0:
            run.append(q.copy())
        if progress is not None and k % tenth == 0 and k // tenth < 10:
            progress(f'spring sample snapshot run (every spring): step {k} of {steps}')
    run = np.array(run)
    rng = np.random.default_rng(seed)
    spread = run.std(axis=0) + 1e-12 * np.abs(run).max()
    random = run.mean(axis=0) + RANDOM_SPREAD * spread * rng.standard_normal(
        (int(RANDOM_SHARE * len(run)), run.shape[1]))
    train_part = np.concatenate([run[0::2], random[0::2]])
    held_part = np.concatenate([run[1::2], random[1::2]])
    return train_part, held_part


def sample_key(exact: ExactForces, phi: np.ndarray, tolerance: float) -> str:
    """Return a hash of what a sample depends on: the springs, the coordinates, the tolerance."""
    h = hashlib.sha256()
    h.update(exact.law.name.encode())
    for array in (exact.law.stiffness, exact.law.rest_length, exact.rest_deltas, phi):
        h.update(np.ascontiguousarray(array).tobytes())
    h.update(repr(float(tolerance)).encode())
    return h.hexdigest()[:32]


def sample_arrays(sample: SpringSample, check_error: float) -> dict[str, np.ndarray]:
    """
    Return what a store keeps of ``sample`` (read back by :func:`validated_sample`).

    ``check_error``: its force error on :func:`check_states` as it is stored.
    """
    return {'springs': sample.springs, 'weights': sample.weights,
            'training_error': np.float64(sample.training_error),
            'held_out_error': np.float64(sample.held_out_error),
            'check_error': np.float64(check_error), 'gave_up': np.str_(sample.gave_up)}


def cached_sample(exact: ExactForces, phi: np.ndarray, omega2: np.ndarray,
                  damping: np.ndarray, dt: float, tolerance: float,
                  progress: Callable[[str], None] | None = None,
                  worker: WorkerProcess | None = None,
                  store: SampleStore | None = None) -> SpringSample:
    """
    Return the sample for these coordinates: from ``store``, else trained (and stored).

    With ``worker``, training runs in that process (its progress is not reported then): the
    caller's other threads, a node's stream, keep the interpreter to themselves.
    """
    key = sample_key(exact, phi, tolerance)
    if store is not None:
        try:
            entry = store.load(key)
            if entry is not None:
                return validated_sample(entry, exact, omega2, tolerance)
        except CacheEntryError as exc:  # reported, removed, trained again
            if progress is not None:
                progress(f'sample cache entry {store.where(key)} refused: {exc}; removed, '
                         'training again')
            store.discard(key)
    if worker is not None:
        if progress is not None:
            progress(f'sampling {exact.n_springs} springs in a worker process')
        sample = worker.call(trained_sample, exact, omega2, damping, dt, tolerance)
    else:
        sample = trained_sample(exact, omega2, damping, dt, tolerance, progress)
    if store is not None:
        check = 0.0 if sample.gave_up else relative_error(exact, sample,
                                                          check_states(exact, omega2))
        store.save(key, sample_arrays(sample, check))
    return sample


def validated_sample(entry: Mapping[str, np.ndarray], exact: ExactForces, omega2: np.ndarray,
                     tolerance: float) -> SpringSample:
    """
    Return the sample a store's entry holds, validated as any input is.

    Its arrays (present, shapes, types, indices in range and distinct, weights finite and not
    negative, errors finite), then its force error recomputed on a few states of the scene (its
    static sag under gravity, scaled, and seeded random states of that size), which must be the
    one recorded when it was stored: an entry that was truncated, flipped or written by hand
    cannot reach the stream, and one valid for its key is used by every later process (the
    run's own checks watch it as they watch a sample just trained).

    :raises CacheEntryError: what is wrong with it.
    """
    try:
        springs, weights = np.asarray(entry['springs']), np.asarray(entry['weights'])
        training = float(entry['training_error'])
        held_out = float(entry['held_out_error'])
        gave_up = str(entry['gave_up']) if 'gave_up' in entry else ''
        recorded = float(entry['check_error']) if 'check_error' in entry else math.nan
    except (KeyError, ValueError, TypeError) as exc:
        raise CacheEntryError(f'unreadable ({type(exc).__name__}: {exc})') from None
    if springs.ndim != 1 or springs.size == 0 or not np.issubdtype(springs.dtype, np.integer):
        raise CacheEntryError('its springs are not a list of spring indices')
    if weights.shape != springs.shape or not np.issubdtype(weights.dtype, np.floating):
        raise CacheEntryError('its weights do not match its springs')
    if springs.min() < 0 or springs.max() >= exact.n_springs:
        raise CacheEntryError(f'a spring index is out of range (the scene has '
                              f'{exact.n_springs} springs)')
    if np.unique(springs).size != springs.size:
        raise CacheEntryError('a spring is listed twice')
    if not (np.isfinite(weights).all() and weights.min() >= 0.0):
        raise CacheEntryError('a weight is negative or not finite')
    if not (math.isfinite(training) and training >= 0.0
            and (math.isnan(held_out) or held_out >= 0.0)):
        raise CacheEntryError('its recorded errors are not errors')
    sample = SpringSample(springs.astype(np.int64), weights.astype(float), training, held_out,
                          0.0, gave_up)
    if gave_up:  # used for nothing but the report: the forces are exact
        return sample
    error = relative_error(exact, sample, check_states(exact, omega2))
    if math.isfinite(recorded):
        if not math.isclose(error, recorded, rel_tol=CHECK_ROUND_OFF, abs_tol=1e-12):
            raise CacheEntryError(f'its force error on check states is {error:.6g}, where '
                                  f'{recorded:.6g} was recorded with it')
    elif not error <= CHECK_FACTOR * tolerance:
        raise CacheEntryError(f'its force error on check states is {error:.3g}, beyond '
                              f'{CHECK_FACTOR:g} x the tolerance {tolerance:g}')
    return sample


def check_states(exact: ExactForces, omega2: np.ndarray) -> np.ndarray:
    """
    Return a few states to check a sample on (``CHECK_STATES``, m).

    The static sag under gravity at half, full and one and a half times its size, and that sag
    moved by a fifth of its size in a seeded random direction (the states a sample is trained
    on are the scene's own motion, which starts from that sag; a scene without gravity: its
    first coordinate at 1e-3 in place of the sag).
    """
    sag = exact.gravity() / np.maximum(omega2, 1e-300)
    if not np.any(sag):  # relative errors of small states hardly depend on their size
        sag = np.zeros(omega2.size)
        sag[0] = 1e-3
    size = float(np.linalg.norm(sag))
    step = np.random.default_rng(0).standard_normal(sag.size)
    states = [sag * scale for scale in (0.5, 1.0, 1.5)]
    states.append(sag + 0.2 * size * step / np.linalg.norm(step))
    return np.array(states[:CHECK_STATES])


def trained_sample(exact: ExactForces, omega2: np.ndarray, damping: np.ndarray,
                   dt: float, tolerance: float,
                   progress: Callable[[str], None] | None = None) -> SpringSample:
    """Return a sample trained on the snapshots of the scene's own motion (its time: both)."""
    start = time.perf_counter()
    snapshots, held_out = training_snapshots(exact, omega2, damping, dt, progress=progress)
    sample = train(exact, snapshots, held_out, TRAINING_SHARE * tolerance, progress)
    return dataclasses.replace(sample, seconds=time.perf_counter() - start)

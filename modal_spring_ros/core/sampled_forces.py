"""
Generalized forces with the springs sampled (ECSW).

A step whose cost does not depend on the number of springs.

:class:`SampledForces` is called like
:class:`~modal_spring_ros.core.forces.GeneralizedForces`: ``forces(q, t)``. The spring force is
the weighted sum over the sampled springs (:mod:`~modal_spring_ros.core.spring_sampling`),
still nonlinear (eq. 20 on each sampled spring); the loads stay exact. At a low rate
(``check_every`` calls, by default spaced by the cost of a check, :func:`check_spacing`) the
exact force is evaluated beside it: the relative difference is
``sample_error`` (its largest value ``max_sample_error``), and the largest spring strain of
that evaluation is what divergence detection sees until the next one (the sampled springs'
strain otherwise). The sample is trained to half the tolerance; if its error on states it was
not trained on, or at run time, passes ``tolerance``, the forces fall back to exact ones for
good (``fell_back``), and the simulation reports it.

The sample is trained per set of coordinates from snapshots of the scene's own motion
(:func:`training_snapshots`) and cached on disk (:func:`cached_sample`), keyed by a hash of the
scene, the coordinates and the tolerance, so a restart does not train again.
"""
from __future__ import annotations

import dataclasses
import hashlib
import math
import os
from pathlib import Path
import time
from typing import Callable
import zipfile

from modal_spring_ros.core.forces import GeneralizedForces, pull_springs
from modal_spring_ros.core.integrators import DiagonalOperators, integrator
from modal_spring_ros.core.spring_sampling import (DEFAULT_TOLERANCE, relative_error,
                                                   SpringSample, train)
from modal_spring_ros.core.worker import WorkerProcess
import numpy as np

#: fewest calls between two checks of the sampled force against the exact one
MIN_CHECK_EVERY = 200
#: a check costs about as much as (springs / sampled springs) sampled evaluations: checks are
#: spaced this many times that apart, so that they add at most a fifth of the sampled springs'
#: own cost and a step stays as cheap on a large scene as on a small one
CHECK_SPACING = 5
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
#: environment variable naming the cache folder ("" disables the cache)
CACHE_ENV = 'MODAL_SPRING_ROS_CACHE'
#: a cache entry's force error is recomputed on this many states when it is loaded, and must be
#: within this many times the tolerance (the states are not its held-out ones)
CHECK_STATES, CHECK_FACTOR = 4, 3.0


class CacheEntryError(ValueError):
    """A sample cache entry that cannot be used; the message says why."""


def training_snapshots(exact: GeneralizedForces, omega2: np.ndarray, damping: np.ndarray,
                       dt: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """
    (training, held-out) snapshots of the coordinates.

    A short exact run from rest (the scene released under its loads), alternately, and random
    states around it.
    """
    fastest = math.sqrt(max(float(omega2.max()), 1e-300))
    dt = max(dt, min(2.0 * math.pi / fastest / TRAINING_STEPS_PER_PERIOD,
                     TRAINING_RUN_S / RUN_SNAPSHOTS))
    ops = DiagonalOperators(1.0, damping, omega2, dt)
    stepper = integrator('explicit' if dt < 2.0 / fastest else 'average')
    steps = max(min(int(round(TRAINING_RUN_S / dt)), TRAINING_STEPS), RUN_SNAPSHOTS)
    every = max(steps // RUN_SNAPSHOTS, 1)
    q = v = np.zeros(omega2.size)
    a = exact(q, 0.0) - damping * v
    run = []
    for k in range(1, steps + 1):
        t = k * dt
        q, v, a, _ = stepper.step(q, v, a, dt, lambda x: exact(x, t), ops)
        if k % every == 0:
            run.append(q.copy())
    run = np.array(run)
    rng = np.random.default_rng(seed)
    spread = run.std(axis=0) + 1e-12 * np.abs(run).max()
    random = run.mean(axis=0) + RANDOM_SPREAD * spread * rng.standard_normal(
        (int(RANDOM_SHARE * len(run)), run.shape[1]))
    train_part = np.concatenate([run[0::2], random[0::2]])
    held_part = np.concatenate([run[1::2], random[1::2]])
    return train_part, held_part


def sample_key(exact: GeneralizedForces, phi: np.ndarray, tolerance: float) -> str:
    """Return a hash of what a sample depends on: the springs, the coordinates, the tolerance."""
    h = hashlib.sha256()
    for array in (exact.stiffness, exact.stiffness_length, exact.rest_deltas, phi):
        h.update(np.ascontiguousarray(array).tobytes())
    h.update(repr(float(tolerance)).encode())
    return h.hexdigest()[:32]


def cache_folder() -> Path | None:
    """Where samples are kept: ``$MODAL_SPRING_ROS_CACHE``, else the user's cache folder."""
    value = os.environ.get(CACHE_ENV)
    if value == '':
        return None
    if value:
        return Path(value)
    base = os.environ.get('XDG_CACHE_HOME') or os.path.join(os.path.expanduser('~'), '.cache')
    return Path(base) / 'modal_spring_ros' / 'samples'


def cached_sample(exact: GeneralizedForces, phi: np.ndarray, omega2: np.ndarray,
                  damping: np.ndarray, dt: float, tolerance: float = DEFAULT_TOLERANCE,
                  progress: Callable[[str], None] | None = None,
                  worker: WorkerProcess | None = None) -> SpringSample:
    """
    Return the sample for these coordinates: from the cache, else trained (and cached).

    With ``worker``, training runs in that process (its progress is not reported then): the
    caller's other threads, a node's stream, keep the interpreter to themselves.
    """
    folder = cache_folder()
    path = folder / f'{sample_key(exact, phi, tolerance)}.npz' if folder else None
    if path is not None and path.is_file():
        try:
            return loaded_sample(path, exact, omega2, tolerance)
        except CacheEntryError as exc:  # reported, removed, trained again
            if progress is not None:
                progress(f'sample cache entry {path} refused: {exc}; removed, training again')
            try:
                path.unlink()
            except OSError:
                pass
    if worker is not None:
        if progress is not None:
            progress(f'sampling {exact.n_springs} springs in a worker process')
        sample = worker.call(trained_sample, exact, omega2, damping, dt, tolerance)
    else:
        sample = trained_sample(exact, omega2, damping, dt, tolerance, progress)
    if path is not None:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_suffix('.tmp.npz')
            np.savez(tmp, springs=sample.springs, weights=sample.weights,
                     training_error=sample.training_error,
                     held_out_error=sample.held_out_error, gave_up=np.str_(sample.gave_up))
            os.replace(tmp, path)
        except OSError:
            pass  # an unwritable cache only costs training again
    return sample


def loaded_sample(path: Path, exact: GeneralizedForces, omega2: np.ndarray,
                  tolerance: float) -> SpringSample:
    """
    Return the sample a cache entry holds, validated as any input is.

    Its arrays (shapes, types, indices in range and distinct, weights finite and not negative,
    errors finite), then its force error recomputed on a few states of the scene (its static
    sag under gravity, scaled, and seeded random states of that size): an entry that was
    truncated, flipped or written by hand cannot reach the stream.

    :raises CacheEntryError: what is wrong with it.
    """
    try:
        with np.load(path, allow_pickle=False) as data:
            springs, weights = np.asarray(data['springs']), np.asarray(data['weights'])
            training = float(data['training_error'])
            held_out = float(data['held_out_error'])
            gave_up = str(data['gave_up']) if 'gave_up' in data.files else ''
    except (OSError, KeyError, ValueError, TypeError, EOFError, zipfile.BadZipFile) as exc:
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
    if not error <= CHECK_FACTOR * tolerance:
        raise CacheEntryError(f'its force error on check states is {error:.3g}, beyond '
                              f'{CHECK_FACTOR:g} x the tolerance {tolerance:g}')
    return sample


def check_states(exact: GeneralizedForces, omega2: np.ndarray) -> np.ndarray:
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


def check_spacing(springs: int, sampled: int) -> int:
    """Return the calls between two checks: a check's cost spread thin (at least 200)."""
    return max(MIN_CHECK_EVERY, math.ceil(CHECK_SPACING * springs / max(sampled, 1)))


def trained_sample(exact: GeneralizedForces, omega2: np.ndarray, damping: np.ndarray,
                   dt: float, tolerance: float,
                   progress: Callable[[str], None] | None = None) -> SpringSample:
    """Return a sample trained on the snapshots of the scene's own motion (its time: both)."""
    start = time.perf_counter()
    snapshots, held_out = training_snapshots(exact, omega2, damping, dt)
    sample = train(exact, snapshots, held_out, TRAINING_SHARE * tolerance, progress)
    return dataclasses.replace(sample, seconds=time.perf_counter() - start)


class SampledForces:
    """``Q(q, t)`` with the springs sampled; see the module text."""

    def __init__(self, exact: GeneralizedForces, sample: SpringSample,
                 tolerance: float = DEFAULT_TOLERANCE, check_every: int | None = None):
        self.exact = exact
        self.sample = sample
        self.tolerance = tolerance
        self.check_every = int(check_every or check_spacing(exact.n_springs, sample.count))
        d = exact.dimension
        springs = sample.springs
        self._g = exact.g_rows_of(springs).reshape(d * springs.size, -1)      # (d k, m)
        self._gt = np.ascontiguousarray(-self._g.T)
        rest = exact.rest_deltas.reshape(d, -1)[:, springs]
        self._rest = rest.ravel()
        self._k = exact.stiffness[springs]
        self._kl = exact.stiffness_length[springs]
        self._inv_l = self._k / self._kl                                   # 1 / l
        self._w = sample.weights
        self._d = d
        self.fell_back = not sample.held_out_error <= tolerance   # NaN: never checked
        self.restart()

    def restart(self) -> None:
        self._calls = 0
        self.sample_error = 0.0
        self.max_sample_error = 0.0
        self.last_max_strain = 0.0
        self._checked_strain = 0.0

    def spring_forces(self, q: np.ndarray) -> np.ndarray:
        if self.fell_back:
            force = self.exact.spring_forces(q)
            self.last_max_strain = self.exact.last_max_strain
            return force
        self._calls += 1
        delta = (self._g @ q + self._rest).reshape(self._d, -1)
        strain = pull_springs(delta, self._k, self._kl, self._inv_l)
        delta *= self._w
        force = self._gt @ delta.ravel()
        if self._calls % self.check_every == 1 or self.check_every == 1:
            exact = self.exact.spring_forces(q)
            scale = max(float(np.linalg.norm(exact)), float(np.linalg.norm(self.exact.gravity())),
                        1e-300)
            self.sample_error = float(np.linalg.norm(force - exact)) / scale
            self.max_sample_error = max(self.max_sample_error, self.sample_error)
            self._checked_strain = self.exact.last_max_strain
            if not self.sample_error <= self.tolerance:  # NaN too
                self.fell_back = True
                force = exact
        self.last_max_strain = max(strain, self._checked_strain)
        return force

    def describe(self) -> str:
        sample = self.sample
        if sample.gave_up:
            return f'exact ({sample.gave_up})'
        if self.fell_back:
            return (f'exact (the {sample.count}-spring sample fell back: error '
                    f'{max(self.max_sample_error, sample.held_out_error):.2%} beyond '
                    f'{self.tolerance:.2%})')
        return (f'sampled: {sample.count} of {self.exact.n_springs} springs, held-out error '
                f'{sample.held_out_error:.2%}, run-time {self.max_sample_error:.2%}')

    def __call__(self, q: np.ndarray, t: float) -> np.ndarray:
        force = self.spring_forces(q)
        force += self.exact.loads(t)
        return force

    def loads(self, t: float) -> np.ndarray:
        return self.exact.loads(t)

    def gravity(self) -> np.ndarray:
        return self.exact.gravity()

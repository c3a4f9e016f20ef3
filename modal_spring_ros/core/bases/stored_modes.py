"""
A large scene's lowest modes kept between runs, and checked when they are read back.

Solving for the lowest modes of a large scene is most of its start (the 100k-particle sheet's
32 modes: about two minutes), and they depend only on the scene's rest stiffness and masses. A
basis handed a store (the :class:`~modal_spring_ros.core.forces.base.SampleStore` that keeps
spring samples: :mod:`~modal_spring_ros.runs.sample_cache` on disk) keeps the modes it solved for
under a hash of the free DOF's stiffness and masses, and the next run of the same scene reads
them back instead of solving: its spring samples, keyed by these very modes, then serve too.

A stored entry is input: its arrays must have the scene's shape, be finite and ascending, be
mass-orthonormal, and satisfy ``K phi = omega^2 M phi`` to a small residual (one sparse product
with every mode, a fraction of the solve). One that does not is refused with the reason, removed,
and the modes are solved for again.
"""
from __future__ import annotations

import hashlib
from typing import Mapping

from modal_spring_ros.core.bases.mass_products import mass_gram
from modal_spring_ros.core.forces.samples import CacheEntryError
from modal_spring_ros.core.model.model import MassSpringModel
import numpy as np

#: Largest residual ``|K phi - omega^2 M phi| / |K phi|`` of a stored mode accepted.
RESIDUAL_RTOL = 1e-6
#: Largest departure of a stored basis from ``Phi^T M Phi = I`` accepted.
ORTHONORMAL_ATOL = 1e-6
#: What an entry's key starts with (the store also keeps samples).
KEY_PREFIX = 'modes-'


def modes_key(model: MassSpringModel) -> str:
    """Return a hash of what the modes depend on: the free DOF's rest stiffness and masses."""
    stiffness = model.stiffness_free.tocsr()
    h = hashlib.sha256()
    h.update(np.int64(model.n_free_dof).tobytes())
    for array in (stiffness.indptr, stiffness.indices, stiffness.data, model.mass_dof):
        h.update(np.ascontiguousarray(array).tobytes())
    return KEY_PREFIX + h.hexdigest()[:32]


def modes_arrays(omega: np.ndarray, vectors: np.ndarray) -> dict[str, np.ndarray]:
    """Return what a store keeps of a basis's modes (read back by :func:`validated_modes`)."""
    return {'omega': np.asarray(omega, dtype=float), 'vectors': np.asarray(vectors, dtype=float)}


def validated_modes(entry: Mapping[str, np.ndarray], model: MassSpringModel
                    ) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the stored ``(omega, vectors)`` of ``model``, checked.

    :raises CacheEntryError: what is wrong with the entry.
    """
    try:
        omega = np.asarray(entry['omega'], dtype=float)
        vectors = np.asarray(entry['vectors'], dtype=float)
    except (KeyError, TypeError, ValueError) as exc:
        raise CacheEntryError(f'not a modes entry ({type(exc).__name__}: {exc})') from None
    n = model.n_free_dof
    if omega.ndim != 1 or vectors.shape != (n, omega.size) or omega.size == 0:
        raise CacheEntryError(f'shapes {omega.shape} and {vectors.shape} are not the modes of '
                              f'{n} free DOF')
    if not (np.all(np.isfinite(omega)) and np.all(np.isfinite(vectors))):
        raise CacheEntryError('non-finite values')
    if np.any(omega <= 0.0) or np.any(np.diff(omega) < 0.0):
        raise CacheEntryError('frequencies not positive and ascending')
    mass = model.mass_dof
    gram = mass_gram(vectors, mass)
    departure = float(np.max(np.abs(gram - np.eye(omega.size))))
    if departure > ORTHONORMAL_ATOL:
        raise CacheEntryError(f'modes not mass-orthonormal (departure {departure:.3g})')
    stiff = model.stiffness_free @ vectors
    residual = np.linalg.norm(stiff - (omega ** 2) * (mass[:, None] * vectors), axis=0)
    worst = float(np.max(residual / np.maximum(np.linalg.norm(stiff, axis=0), 1e-300)))
    if worst > RESIDUAL_RTOL:
        raise CacheEntryError(f'not modes of this scene (relative residual {worst:.3g})')
    return omega, np.ascontiguousarray(vectors)

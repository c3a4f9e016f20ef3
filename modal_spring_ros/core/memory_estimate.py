"""
What a run holds in memory, by stage, estimated before any stage runs.

A modal run of a large scene builds its model (the sparse stiffness ``K`` and spring-difference
matrix ``D``, assembled from one block per spring), factorises ``K`` (sparse LU, whose fill grows
with the scene's separators: about ``N^(4/3)`` on a sheet, ``N^(7/4)`` in a cube), computes its
``k`` lowest modes (shift-invert Lanczos: ``2k + 1`` Lanczos vectors beside the ``k`` Ritz
vectors), solves one vector per pair of the band's lowest modes for the derivative coordinates,
trains a spring sample on snapshots of every spring's force (sampled springs, and ``modal.auto``,
which may choose them), and steps the ``m`` coordinates it keeps. Each term below counts such
arrays in floats; the coefficients are fitted to the peak resident memory measured on sheets and
blocks of several sizes (``test/bench/test_memory.py``; ``modal_spring_bench --suite scale`` up
to 500,000 particles). Memory a stage frees is not always given back to the system before the
next one grows, so the stages add up rather than take turns.

Pure: counts in, bytes out; :func:`run_size` reads the counts from a scene and a run's options,
:func:`check_run_memory` refuses a run that does not fit in the memory it is handed (the front
ends pass :func:`~modal_spring_ros.scenes.fields.limits.available_memory`) before any stage runs.
"""
from __future__ import annotations

import dataclasses
import math

from modal_spring_ros.core.bases.basis import DEFAULT_MAX_MODES, DENSE_LIMIT, INITIAL_MODES
from modal_spring_ros.core.bases.derivatives import MAX_PAIR_MODES, PAIR_SOLVES_BYTES
from modal_spring_ros.core.model.scene import Scene, SceneError
import numpy as np

#: Bytes of a float64.
FLOAT = 8
#: Bytes a stored entry of a sparse LU factor takes at the factorisation's peak (its value; the
#: row indices are shared by the columns of a supernode).
FACTOR_ENTRY = 9
#: Bytes a spring keeps in the model, per entry of its d x d blocks (K's four blocks in
#: compressed rows, D, the spring arrays; the assembly's triplets are freed for later stages).
MODEL_PER_BLOCK_ENTRY = 21
#: Bytes a particle's own arrays take (positions, masses, DOF maps), about.
MODEL_PER_PARTICLE = 100
#: Bytes any run takes beyond its arrays (modules loaded on first use, allocator arenas, BLAS
#: buffers).
OVERHEAD = 11 * 2**20
#: The counts' sums fit the measured peaks of sheets and blocks within 0.84-1.17: times this
#: margin the estimate is a bound (1.0-1.4 times the peak), not a median.
MARGIN = 1.4
#: Entries of a sparse LU factor of ``n`` DOF, ``c n^e``, by the scene's effective dimension
#: (particles ~ layers^D, layers across its longest extent): (D, e, c) measured with the
#: nested dissection ordering of :func:`~.model.definite_factor.factor_definite` on strips,
#: sheets and cubes of 4k-200k DOF (sheets of 1,700-200,000 DOF and cubes of 1,300-64,000
#: within 0.90-1.0), interpolated between them.
FILL_BY_DIMENSION = ((1.0, 1.0, 20.7), (2.0, 1.155, 26.7), (3.0, 1.467, 8.43))
#: Vectors of n floats the eigensolver holds per Lanczos vector (ARPACK's workspace) and, beyond
#: them, per mode computed (the Ritz vectors, the basis kept and the one it grows from), fitted
#: to the measured peaks (a run is built once, at its step: its stages' peaks no longer overlap)
MODES_VECTORS_PER_LANCZOS = 0.9
MODES_VECTORS_PER_MODE = 1.5
#: Vectors of n floats a derivative pair holds (its solved vector, its share of the Gram's
#: blocks), beside its solve a basis keeps (up to ``PAIR_SOLVES_BYTES`` of them).
DERIVATIVE_VECTORS_PER_PAIR = 0.7
#: Vectors of n floats a stepped coordinate adds (the stepped shapes gathered from the basis;
#: their transpose and float32 copy take the eigensolver's freed workspace).
RUN_VECTORS_PER_COORDINATE = 1.0
#: Spring vectors (d x E floats) a spring sample's training holds at once (each of its 60
#: training snapshots' per-spring forces, and one chunk of snapshots' products with the
#: residual: :data:`~modal_spring_ros.core.forces.sampling.SNAPSHOT_CHUNK`).
SAMPLE_SPRING_VECTORS = 80
#: Dense eigensolver (every mode of a small scene): n x n matrices held at once.
DENSE_MATRICES = 4


@dataclasses.dataclass(frozen=True)
class RunSize:
    """The counts a run's memory follows."""

    particles: int
    dof: int                  # free degrees of freedom, n
    springs: int
    dimension: int
    layers: float             # particles across the scene's longest extent
    modes: int                # rest modes computed, k
    stepped: int              # coordinates stepped, m
    pairs: int                # derivative pairs solved
    pair_modes: int
    sampled: bool             # a spring sample is trained
    dense: bool               # every mode by the dense solver
    factor_entries: int | None = None  # known once factorised


@dataclasses.dataclass(frozen=True)
class MemoryEstimate:
    """Peak resident bytes of a run, and what each stage adds to it."""

    stages: tuple[tuple[str, int], ...]

    @property
    def total(self) -> int:
        return sum(b for _, b in self.stages)

    def text(self) -> str:
        """Return e.g. ``about 13.8 GiB (model 0.9, factor 2.1, modes 6.3, run 4.5)``."""
        parts = ', '.join(f'{name} {b / 2**30:.2g}' for name, b in self.stages if b)
        return f'about {self.total / 2**30:.3g} GiB ({parts})'


def factor_entries(dof: int, particles: int, layers: float) -> int:
    """Return the entries a sparse LU of ``K`` takes, from its size and its layers across."""
    dims, powers, scales = (np.array(c) for c in zip(*FILL_BY_DIMENSION))
    span = math.log(max(layers, 2.0))
    effective = float(np.clip(math.log(max(particles, 2)) / span, dims[0], dims[-1]))
    power = float(np.interp(effective, dims, powers))
    scale = math.exp(float(np.interp(effective, dims, np.log(scales))))
    return int(scale * max(dof, 1) ** power)


def estimate(size: RunSize) -> MemoryEstimate:
    """Return the peak resident memory of a run of ``size``, by stage."""
    n, d = size.dof, size.dimension
    model = (size.springs * MODEL_PER_BLOCK_ENTRY * 4 * d * d
             + size.particles * MODEL_PER_PARTICLE)
    if size.dense:
        modes = DENSE_MATRICES * FLOAT * n * n
        factor = 0
    else:
        entries = size.factor_entries if size.factor_entries is not None \
            else factor_entries(n, size.particles, size.layers)
        factor = FACTOR_ENTRY * entries
        lanczos = min(n, max(2 * size.modes + 1, 20))
        modes = FLOAT * n * int(MODES_VECTORS_PER_LANCZOS * lanczos
                                + MODES_VECTORS_PER_MODE * size.modes)
    # the pair solves a basis keeps for the bands that share them, where it keeps them
    kept = n * size.pairs if FLOAT * n * size.pairs <= PAIR_SOLVES_BYTES else 0
    derivatives = FLOAT * (DERIVATIVE_VECTORS_PER_PAIR * n * size.pairs + kept
                           + d * size.springs * size.pair_modes)
    sample = FLOAT * d * size.springs * SAMPLE_SPRING_VECTORS if size.sampled else 0
    run = FLOAT * n * RUN_VECTORS_PER_COORDINATE * size.stepped
    stages = (('model', model + OVERHEAD), ('factor', factor), ('modes', modes),
              ('derivatives', derivatives), ('spring sample', sample), ('run', run))
    return MemoryEstimate(tuple((name, int(MARGIN * b)) for name, b in stages))


def layers_across(positions: np.ndarray, spacing: float) -> float:
    """
    Return how many particle layers span the longest extent of ``positions``.

    The extent along the first principal axis, as a uniform spread of that standard deviation
    spans (``sqrt(12) sigma``): a square's side whichever way it is turned.
    """
    points = np.asarray(positions, dtype=float)
    if points.shape[0] < 2 or not spacing > 0.0:
        return 1.0
    sample = points[:: max(1, points.shape[0] // 20000)]
    sample = sample - sample.mean(axis=0)
    sigma = float(np.linalg.svd(sample, compute_uv=False)[0]) / math.sqrt(sample.shape[0])
    return math.sqrt(12.0) * sigma / spacing + 1.0


def run_size(scene: Scene, config) -> RunSize:
    """
    Return the counts of a run of ``scene`` with ``config`` (a :class:`SimulationConfig`).

    An upper bound where the modes computed follow frequencies not known yet: up to
    ``config.max_modes`` (or its default).
    """
    dof = int(scene.n_free_dof)
    dense = dof <= DENSE_LIMIT
    modal = config.method == 'modal'
    cap = min(int(config.max_modes) if config.max_modes else DEFAULT_MAX_MODES, dof)
    band = config.band
    if not modal:
        modes, kept = min(INITIAL_MODES, dof), 0
    elif band.by == 'index' and band.bounded_above and not config.auto:
        kept = min(int(band.top) + 1, cap)
        modes = max(min(INITIAL_MODES, dof), kept)
    else:
        modes = kept = max(min(INITIAL_MODES, dof), cap)
    added = (config.derivative_directions + 4
             if modal and (config.basis == 'derivatives' or config.auto) else 0)
    pair_modes = min(kept, MAX_PAIR_MODES) if added else 0
    lengths = np.asarray(scene.rest_length, dtype=float)
    spacing = float(np.median(lengths)) if lengths.size else 1.0
    return RunSize(
        particles=scene.n_particles, dof=dof, springs=scene.n_springs,
        dimension=int(scene.dimension), layers=layers_across(scene.rest_positions, spacing),
        modes=dof if dense else modes, stepped=kept + added,
        pairs=pair_modes * (pair_modes + 1) // 2, pair_modes=pair_modes,
        sampled=modal and (config.forces == 'sampled' or config.auto), dense=dense)


class MemoryLimitError(SceneError):
    """A run of a scene would take more memory than the machine has available."""


def check_run_memory(scene: Scene, config, have: int) -> MemoryEstimate:
    """
    Refuse a run that would not fit in ``have`` bytes (what the machine has available).

    :raises MemoryLimitError: naming the estimate by stage and what is available.
    """
    need = estimate(run_size(scene, config))
    if need.total > have:
        raise MemoryLimitError(
            f"scene '{scene.name}': this run needs {need.text()} and {gib(have)} are "
            'available: narrow the band (filter.high_hz or filter.high_mode), lower '
            'modal.max_modes, use modal.basis rest, or a coarser scene')
    return need


def gib(value: float) -> str:
    """Return bytes as GiB with three figures."""
    return f'{value / 2**30:.3g} GiB'

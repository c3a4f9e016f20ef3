"""
Model no more than a scene needs: the fewest modes (and the step) that meet a tolerance.

The loads of a scene are gravity and the base excitation of its anchor motion (an inertial
load ``-M 1_axis`` per moving axis). For a load ``f`` the static response is
``u = K^-1 f``, and in mass-normalised modes ``u = sum_i phi_i (phi_i^T f) / omega_i^2``, so
the share of ``u`` that the modes ``R`` miss is, exactly,

    e_R(f) = sqrt(1 - sum_{i in R} (phi_i^T f)^2 / omega_i^4 / ||u||_M^2)

with ``||u||_M^2 = u^T M u`` from one sparse solve: no other mode is needed. A step load (the
sheet released under gravity) excites each mode with exactly its static share, so the same
number bounds the dynamic truncation error; a harmonic load at ``f_exc`` amplifies the first
dropped mode by ``1 / (1 - (f_exc / f_i)^2)``, which a frequency margin keeps small.

:func:`choose_modes` adds modes (lowest first, within the filter band) until every load's
predicted error is within its share of the tolerance and the highest kept mode is at least
``margin`` times the highest driving frequency. :func:`choose_step` then picks the largest step
that is stable (explicit: ``2 / omega_max`` of the kept modes, with a safety factor) and
accurate within the other share. Newmark (gamma 1/2) has no amplitude error but a relative
period error of about ``(omega dt)^2 / 24``; for modes ringing freely it accumulates into a
phase error ``omega t (omega dt)^2 / 24``, which averaged over their decay time ``tau`` (at
most ``HORIZON_S``) is ``omega (tau / 2) (omega dt)^2 / 24``, evaluated at the
response-weighted frequency of the kept modes
(``omega_eff^2 = sum s_i omega_i^2 / sum s_i``, ``s_i`` the mode's share of the static
response); the forced response needs ``(omega_exc dt)^2 / 12`` within it too. The two shares are
``SHARE * tolerance`` each, so that together (in quadrature) they stay within the tolerance.

:func:`choose_refresh` sets how often the nonlinear spring forces are evaluated
(:mod:`modal_spring_ros.core.forces.refreshed`): every ``REFRESH_PERIODS`` of a period of the
highest kept mode, so that between evaluations no kept mode moves through more than half an
oscillation along the static tangent. (The benchmark measures what this costs in accuracy:
on the sheets at 1 %, nothing measurable against evaluating on every step.)
"""
from __future__ import annotations

import dataclasses
import math
from typing import Callable

from modal_spring_ros.core.bases.basis import DEFAULT_MAX_MODES, ModalBasis
from modal_spring_ros.core.bases.basis_choice import BasisChoice
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.integrators import stable_step
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.motion.frame_loads import frame_load_patterns
import numpy as np
import scipy.sparse.linalg as spla

DEFAULT_TOLERANCE = 0.01
DEFAULT_MARGIN = 2.0
STABILITY_SAFETY = 0.9
#: share of the tolerance given to mode truncation and to time stepping each
SHARE = 0.7
#: longest time over which a free mode's phase error is counted, s
HORIZON_S = 2.0
#: the spring forces are evaluated at least this often, in periods of the highest kept mode
REFRESH_PERIODS = 0.5
#: and at least every this many steps
MAX_REFRESH = 200


@dataclasses.dataclass(frozen=True)
class ModeChoice:
    count: int                      # modes kept
    modes: np.ndarray               # their indices
    predicted_error: float          # worst load's static truncation error
    load_errors: dict[str, float]   # per load
    highest_hz: float
    excitation_hz: float
    omega_max: float                # rad/s, highest kept mode
    omega_eff: float                # rad/s, response-weighted frequency of the kept modes
    basis: BasisChoice | None = None  # the basis chosen for them, when it was chosen

    def describe(self) -> str:
        text = (f'{self.count} modes up to {self.highest_hz:.4g} Hz, predicted error '
                f'{self.predicted_error:.2%}')
        return text if self.basis is None else f'{text}, {self.basis.describe()}'


def scene_loads(model: MassSpringModel) -> dict[str, np.ndarray]:
    """
    Return the scene's loads by name.

    Gravity, the unit base-excitation load per axis the base moves along, and a turning clamp's
    frame load patterns.
    """
    loads = {}
    if np.any(model.gravity_force != 0.0):
        loads['gravity'] = model.gravity_force
    motion = model.motion
    for axis in sorted({c.axis for c in motion.components if c.amplitude != 0.0}):
        if axis in model.axes:
            a = model.axes.index(axis)
            pattern = np.zeros(model.n_free_dof)
            pattern[a::model.dimension] = -model.mass_dof[a::model.dimension]
            loads[f"base {'xyz'[axis]}"] = pattern
    if model.rotates:  # a turning clamp: gravity turns, and centrifugal and Euler loads
        for k, pattern in enumerate(frame_load_patterns(model)):
            loads[f'turning clamp {k}'] = pattern
    return loads


class TruncationEstimator:
    """Static truncation error of mode sets, for the scene's loads (one sparse LU of K)."""

    def __init__(self, model: MassSpringModel):
        self.model = model
        self.loads = scene_loads(model)
        lu = spla.splu(model.stiffness_free.tocsc())
        self._norm2 = {}
        for name, f in self.loads.items():
            u = lu.solve(f)
            self._norm2[name] = float(u @ (model.mass_dof * u))

    def effective_omega(self, basis: ModalBasis, modes: np.ndarray) -> float:
        """Response-weighted RMS frequency of ``modes`` over all loads (rad/s)."""
        phi = basis.vectors[:, modes]
        w = basis.omega[modes]
        share = np.zeros(modes.size)
        for f in self.loads.values():
            share += (phi.T @ f) ** 2 / w ** 4
        if share.sum() <= 0.0:
            return float(w.max())
        return float(np.sqrt(np.sum(share * w ** 2) / share.sum()))

    def errors(self, basis: ModalBasis, modes: np.ndarray) -> dict[str, float]:
        phi = basis.vectors[:, modes]
        w4 = basis.omega[modes] ** 4
        out = {}
        for name, f in self.loads.items():
            captured = float(np.sum((phi.T @ f) ** 2 / w4))
            share = captured / self._norm2[name] if self._norm2[name] > 0 else 1.0
            out[name] = math.sqrt(max(0.0, 1.0 - min(share, 1.0)))
        return out


def choose_modes(model: MassSpringModel, basis: ModalBasis, band: FilterBand = FilterBand(),
                 tolerance: float = DEFAULT_TOLERANCE, margin: float = DEFAULT_MARGIN,
                 max_modes: int = DEFAULT_MAX_MODES,
                 affords: Callable[[int], bool] | None = None) -> ModeChoice | None:
    """
    Return the fewest lowest modes (within ``band``) meeting ``tolerance`` for every load.

    Computes modes only as far as needed (in growing batches on large scenes). ``affords``
    (given how many modes the next solve solves for) may refuse a solve: None is returned then
    (the modes needed cost more than the caller will pay).
    """
    if not 0.0 < tolerance < 1.0:
        raise ValueError(f'modal.tolerance ({tolerance}) must be between 0 and 1')
    band.validate()
    estimator = TruncationEstimator(model)
    excitation = model.motion.frequencies_hz
    f_exc = float(excitation.max()) if excitation.size else 0.0
    limit = min(max_modes, basis.n_dof)
    while True:
        kept = np.flatnonzero(band.keeps(basis.frequencies_hz))
        kept = kept[kept < limit]
        freqs = basis.frequencies_hz
        for n in range(1, kept.size + 1):
            modes = kept[:n]
            errors = estimator.errors(basis, modes)
            worst = max(errors.values(), default=0.0)
            if worst <= SHARE * tolerance and freqs[modes[-1]] >= margin * f_exc:
                return _choice(estimator, basis, modes, errors, f_exc)
        if basis.complete or basis.count >= limit:
            if not kept.size:
                raise ValueError(f'filter band {band.describe()} keeps no mode')
            return _choice(estimator, basis, kept, estimator.errors(basis, kept), f_exc)
        count = min(max(2 * basis.count, 16), limit)
        if affords is not None and not affords(basis.to_solve(count)):
            return None
        basis.ensure_count(count)


def _choice(estimator, basis, modes, errors, f_exc) -> ModeChoice:
    return ModeChoice(int(modes.size), modes, max(errors.values(), default=0.0), errors,
                      float(basis.frequencies_hz[modes[-1]]), f_exc,
                      float(basis.omega[modes[-1]]), estimator.effective_omega(basis, modes))


def choose_step(choice: ModeChoice, integrator: str, tolerance: float = DEFAULT_TOLERANCE,
                damping=None) -> float:
    """
    Largest step that is stable for the kept modes and accurate.

    Largest step that is stable for the kept modes and accurate within its share of ``tolerance``
    (``damping``: the scene's Damping, for the modes' decay time).
    """
    budget = SHARE * tolerance
    w = choice.omega_eff
    decay = damping.modal_coefficients(np.array([w]))[0] / 2.0 if damping is not None else 0.0
    tau = min(HORIZON_S, 1.0 / decay) if decay > 0 else HORIZON_S
    dt = math.sqrt(48.0 * budget / (w ** 3 * tau))
    if choice.excitation_hz > 0:
        dt = min(dt, math.sqrt(12.0 * budget) / (2 * math.pi * choice.excitation_hz))
    dt = min(dt, STABILITY_SAFETY * stable_step(integrator, choice.omega_max))
    return dt


def choose_refresh(highest_hz: float, dt: float) -> int:
    """
    Step between exact evaluations of the spring forces.

    For kept modes up to ``highest_hz`` stepped at ``dt``.
    """
    interval_s = REFRESH_PERIODS / highest_hz if highest_hz > 0 else math.inf
    return int(min(MAX_REFRESH, max(1, math.floor(interval_s / dt + 1e-9))))

"""Stepping a scene: the modal method (paper fig. 5) and the full physical reference.

:class:`ModalSimulation` steps only the retained modes ``R``. Each step (paper fig. 5):
advance the modal coordinates ``q`` (Newmark), map to positions ``x = x_rest + Phi_R q`` (fixed
particles follow their prescribed motion), evaluate the nonlinear spring forces and gravity in
physical space (eq. 20), project them back, ``Q = Phi_R^T f``, and solve the uncoupled modal
equations ``q'' + C q' = Q``. ``K`` only gives the basis; the dynamics stay nonlinear.

:class:`FullSimulation` steps every free DOF with the same integrators and the equivalent
damping, and is what the modal run is compared with. With every mode kept, the two agree to
round-off.

Both detect divergence on the step it happens (a non-finite state, a spring strained beyond
``strain_limit``, or an implicit step that does not converge), raise :class:`DivergenceError`
and keep the last good state, so no caller ever sees NaN.
"""
from __future__ import annotations

import abc
import dataclasses
import math
import threading
from typing import Callable

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from modal_spring_ros.filter_band import BandError, FilterBand
from modal_spring_ros.generalized_forces import GeneralizedForces
from modal_spring_ros.mass_spring import MassSpringModel
from modal_spring_ros.modal_basis import ModalBasis
from modal_spring_ros.newmark import (INTEGRATORS, DiagonalOperators, NonConvergence,
                                      average_step, explicit_step)
from modal_spring_ros.refreshed_forces import RefreshedForces
from modal_spring_ros.scene import Damping

METHODS = ("modal", "full")

#: Default spring strain treated as divergence (the simulation has left any meaningful regime).
DEFAULT_STRAIN_LIMIT = 1.0


class DivergenceError(RuntimeError):
    """The step diverged. The simulation keeps its last good state."""

    def __init__(self, reason: str, time: float, step: int):
        super().__init__(f"diverged at t = {time:.6g} s (step {step}): {reason}")
        self.reason = reason
        self.time = time
        self.step = step


def stable_step_limit(omega_max: float) -> float:
    """Largest stable explicit Newmark step for an undamped mode: ``2 / omega_max``."""
    return math.inf if omega_max <= 0.0 else 2.0 / omega_max


class Simulation(abc.ABC):
    """What both methods share: time, state in physical terms, divergence checks."""

    method: str

    def __init__(self, model: MassSpringModel, *, dt: float, integrator: str,
                 damping: Damping | None, strain_limit: float):
        if not (dt > 0.0 and math.isfinite(dt)):
            raise ValueError(f"dt ({dt}) must be a positive finite number of seconds")
        if integrator not in INTEGRATORS:
            raise ValueError(f"integrator '{integrator}' must be one of {', '.join(INTEGRATORS)}")
        self.model = model
        self.dt = float(dt)
        self.integrator = integrator
        self.damping = model.scene.damping if damping is None else damping
        self.strain_limit = float(strain_limit)
        self.time = 0.0
        self.steps = 0
        self._t0 = 0.0
        self.last_iterations = 1
        self.diverged: DivergenceError | None = None

    # -- state in physical terms ---------------------------------------------------------------
    @abc.abstractmethod
    def displacement(self) -> np.ndarray:
        """Free-DOF displacement ``u`` from rest, relative to the moving base (flat)."""

    @abc.abstractmethod
    def velocity(self) -> np.ndarray:
        """Free-DOF velocity relative to the base (flat)."""

    @abc.abstractmethod
    def stability_limit(self) -> float:
        """``2 / omega_max`` over the modes this run steps (explicit integrator), s."""

    @abc.abstractmethod
    def reset(self) -> None:
        """Back to the rest shape, at rest, at t = 0."""

    def positions(self) -> np.ndarray:
        """(n, 3) particle positions (scene order)."""
        x = self.model.positions(self.displacement(), self.time)
        return self.model.positions3(x)

    def energy(self) -> dict[str, float]:
        x = self.model.positions(self.displacement(), self.time)
        v = self.velocity().reshape(-1, self.model.dimension) + self.model.base_velocity(self.time)
        return self.model.energy(x, v.ravel())

    def max_strain(self) -> float:
        return self.model.max_strain(self.model.positions(self.displacement(), self.time))

    # -- stepping ------------------------------------------------------------------------------
    def step(self, count: int = 1) -> None:
        """Advance ``count`` steps. Raises :class:`DivergenceError` (state kept at last good)."""
        for _ in range(count):
            self._step_once()

    def _checked(self, a1: np.ndarray) -> None:
        """Divergence checks of a step. ``u1`` and ``v1`` derive from the (finite) last state
        and ``a1``, so a finite ``a1`` (squared norm, which also catches overflow) is enough."""
        t1 = self.time + self.dt
        reason = None
        if not math.isfinite(float(a1 @ a1)):
            reason = "non-finite state"
        elif self._forces.last_max_strain > self.strain_limit:
            reason = (f"spring strain {self._forces.last_max_strain:.3g} exceeds the limit "
                      f"{self.strain_limit:g}")
        if reason is not None:
            self.diverged = DivergenceError(reason, t1, self.steps + 1)
            raise self.diverged

    def _advance(self, u, v, a, force: Callable[[np.ndarray], np.ndarray], ops):
        """One integrator step in whatever coordinates ``u`` is; checks, does not commit."""
        if self.integrator == "explicit":
            u1, v1, a1 = explicit_step(u, v, a, self.dt, force, ops)
            self.last_iterations = 1
        else:
            try:
                u1, v1, a1, self.last_iterations = average_step(u, v, a, self.dt, force, ops)
            except NonConvergence as exc:
                self.diverged = DivergenceError(str(exc), self.time + self.dt, self.steps + 1)
                raise self.diverged from None
        self._checked(a1)
        return u1, v1, a1

    def _commit(self) -> None:
        self.steps += 1
        self.time = self._t0 + self.steps * self.dt
        self.diverged = None

    def take_over(self, other: "Simulation") -> None:
        """Continue from another simulation's physical state and time (a settings change)."""
        self._t0, self.steps, self.time = other.time, 0, other.time
        self.set_state(other.displacement(), other.velocity())

    @abc.abstractmethod
    def set_state(self, displacement: np.ndarray, velocity: np.ndarray) -> None:
        """Start from a free-DOF displacement and velocity (relative to the base)."""

    @abc.abstractmethod
    def _step_once(self) -> None:
        ...


# ----------------------------------------------------------------------------------------------
# Modal


#: Stepped-mode sets a modal run keeps prepared ahead (a switch needs two: the modes stepped
#: during its transition and after it); the oldest goes first.
PREPARED_SETS_KEPT = 4


@dataclasses.dataclass(frozen=True)
class _SteppedSet:
    """What stepping one set of modes needs: shapes, ``omega^2``, damping, operators, forces."""

    phi: np.ndarray
    omega2: np.ndarray
    damping: np.ndarray
    ops: DiagonalOperators
    forces: GeneralizedForces | RefreshedForces


class ModalSimulation(Simulation):
    """The seed method: step only the modes the filter band keeps.

    Changing the band while running is smooth: a mode that leaves the band fades out over
    ``transition_s`` (its amplitude follows a raised-cosine envelope to zero, so positions do
    not jump); a mode that enters starts from rest and takes on its load along the same
    envelope, so it eases into place rather than dropping. Modes not computed yet are computed
    when a band first needs them (at most ``max_modes``).

    ``force_refresh`` (steps): 1 evaluates the nonlinear spring forces on every step, exactly
    as the paper; ``N > 1`` evaluates them every ``N`` steps and continues them along the
    static tangent in between (:mod:`modal_spring_ros.refreshed_forces`), so that most steps
    cost nothing per spring.
    """

    method = "modal"

    def __init__(self, model: MassSpringModel, basis: ModalBasis, band: FilterBand, *,
                 dt: float, integrator: str = "explicit", damping: Damping | None = None,
                 transition_s: float = 0.5, max_modes: int | None = None,
                 strain_limit: float = DEFAULT_STRAIN_LIMIT, highest_hz: float | None = None,
                 force_refresh: int = 1):
        super().__init__(model, dt=dt, integrator=integrator, damping=damping,
                         strain_limit=strain_limit)
        if not (isinstance(force_refresh, (int, np.integer)) and force_refresh >= 1):
            raise ValueError(f"force refresh ({force_refresh}) must be a whole number of "
                             "steps, at least 1")
        self.force_refresh = int(force_refresh)
        self.basis = basis
        #: modes above this frequency are never stepped (set by the automatic mode choice)
        self.highest_hz = highest_hz
        #: the automatic mode choice that set ``highest_hz`` (a ModeChoice), if any
        self.auto = None
        self.max_modes = int(max_modes) if max_modes else (basis.n_dof if basis.dense else 256)
        self.transition_s = float(transition_s)
        self.band = band.validate()
        self._active = np.empty(0, dtype=np.int64)
        self._target = np.empty(0, dtype=bool)
        self._progress = np.empty(0)  # fade progress per active mode: 1 = fully in, 0 = out
        self._fading = False
        self._q = self._v = self._a = np.empty(0)
        self._built: dict[tuple[int, bytes], _SteppedSet] = {}
        self._built_lock = threading.Lock()
        self._set_active(self.select_modes(band))
        self.reset()

    # -- band ----------------------------------------------------------------------------------
    def prepare_band(self, band: FilterBand) -> None:
        """Compute the modes ``band`` needs (the slow part of a band change; no state change)."""
        band.validate()
        limit = min(self.max_modes, self.basis.n_dof)
        top = self.highest_hz if self.highest_hz is not None else math.inf
        if band.by == "index":
            needed = int(band.high) + 1 if band.bounded_above else limit
            self.basis.ensure_count(min(needed, limit))
            if math.isfinite(top):
                self.basis.ensure_frequency(top, limit)
        elif band.bounded_above or math.isfinite(top):
            self.basis.ensure_frequency(min(band.high if band.bounded_above else top, top), limit)
        else:
            self.basis.ensure_count(limit)

    def select_modes(self, band: FilterBand) -> np.ndarray:
        """Indices of the computed modes ``band`` keeps (computing what it needs first).
        Changes no state of the run, so it can check a band before it is applied.

        Raises:
            BandError: the band keeps no mode.
        """
        self.prepare_band(band)
        f = self.basis.frequencies_hz
        keep = np.flatnonzero(band.keeps(f))
        if band.by == "index":
            keep = keep[keep < self.max_modes]
        if self.highest_hz is not None:
            keep = keep[f[keep] <= self.highest_hz * (1.0 + 1e-12)]
        if keep.size == 0:
            span = f"{f[0]:.4g} .. {f[-1]:.4g} Hz" if band.by == "hz" else f"0 .. {f.size - 1}"
            raise BandError(f"filter band {band.describe()} keeps no mode "
                            f"(the computed modes span {span})")
        return keep

    def set_band(self, band: FilterBand, transition_s: float | None = None) -> None:
        """Change the band; leaving modes fade out, entering modes start from rest."""
        keep = self.select_modes(band)
        if transition_s is not None:
            self.transition_s = float(transition_s)
        self.band = band
        self._set_active(keep)

    @property
    def truncated(self) -> bool:
        """The band reaches past the computed modes (capped at ``max_modes``)."""
        top = self.highest_hz if self.highest_hz is not None else math.inf
        band = self.band
        edge = min(band.high if band.bounded_above and band.by == "hz" else math.inf, top)
        return not self.basis.complete and self.basis.frequencies_hz[-1] <= edge

    @property
    def kept_modes(self) -> np.ndarray:
        """Indices of the modes in the band (fading-out modes excluded)."""
        return self._active[self._target]

    @property
    def stepped_modes(self) -> np.ndarray:
        """Indices of the modes being stepped (band plus modes still fading out)."""
        return self._active.copy()

    @property
    def fading(self) -> bool:
        """Some modes are still fading in or out after a band change."""
        return self._fading

    def stability_limit(self) -> float:
        return stable_step_limit(float(self.basis.omega[self._active].max()))

    def prepare_switch(self, band: FilterBand, transition_s: float | None = None) -> None:
        """Do the slow part of a switch to ``band`` ahead, from any thread, while this run
        goes on: compute the modes it needs and build the operators of the modes stepped
        during the transition and after it. :meth:`set_band` then finds them built. Changes
        no state of the run.

        Raises:
            BandError: the band keeps no mode.
        """
        keep = self.select_modes(band)
        instant = (self.transition_s if transition_s is None else transition_s) <= 0.0
        active, progress = self._active, self._progress  # one consistent pair, if unchanged
        if active.size == progress.size:
            self._prepare_set(self._next_active(keep, active, progress, instant))
        self._prepare_set(keep)

    @staticmethod
    def _next_active(keep: np.ndarray, active: np.ndarray, progress: np.ndarray,
                     instant: bool) -> np.ndarray:
        """Modes stepped once ``keep`` is the band: ``keep`` plus the modes still fading out."""
        leaving = active[~np.isin(active, keep) & (progress > 0.0)]
        return np.union1d(keep, leaving[:0] if instant else leaving)

    def _prepare_set(self, active: np.ndarray) -> None:
        """Build the operators of stepping ``active`` and keep them for :meth:`_take_set`."""
        key = (self.basis.count, active.tobytes())
        with self._built_lock:
            if key in self._built:
                return
        built = self._build_set(active)
        with self._built_lock:  # the stepping thread may take from it meanwhile
            self._built[key] = built
            while len(self._built) > PREPARED_SETS_KEPT:  # a switch superseded before use
                self._built.pop(next(iter(self._built)))

    def _take_set(self, active: np.ndarray) -> _SteppedSet:
        """The operators of stepping ``active``: prepared ones (used once), else built now."""
        with self._built_lock:
            built = self._built.pop((self.basis.count, active.tobytes()), None)
        return built if built is not None else self._build_set(active)

    def _build_set(self, active: np.ndarray) -> _SteppedSet:
        phi = np.ascontiguousarray(self.basis.vectors[:, active])
        omega = self.basis.omega[active]
        damp = self.damping.modal_coefficients(omega)
        exact = GeneralizedForces(self.model, phi)
        forces = (exact if self.force_refresh == 1 else
                  RefreshedForces(exact, omega**2, self.force_refresh, self.dt,
                                  self.strain_limit))
        return _SteppedSet(phi, omega**2, damp, DiagonalOperators(1.0, damp, omega**2, self.dt),
                           forces)

    def _set_active(self, keep: np.ndarray) -> None:
        """New active set: ``keep`` plus old modes still fading out. Re-projects the state.

        Each active mode has a fade progress ``p`` in [0, 1] (1 = fully in) and an envelope
        ``w = (1 - cos(pi p)) / 2``. Modes of ``keep`` ramp ``p`` up, the others down.
        """
        keep = np.asarray(keep, dtype=np.int64)
        old_active, old_progress = self._active, self._progress
        instant = self.transition_s <= 0.0
        active = self._next_active(keep, old_active, old_progress, instant)
        target = np.isin(active, keep)
        was = np.isin(active, old_active)
        progress = np.zeros(active.size)  # modes new to the set fade in from 0
        progress[was] = old_progress[np.searchsorted(old_active, active[was])]
        if instant or not old_active.size:
            progress[target] = 1.0
        stepped = self._take_set(active)
        if old_active.size:
            # Map the state onto the new active modes: q_new = Phi_new^T M Phi_old q_old
            # (exact for modes in both sets; modes new to the set start from rest).
            overlap = stepped.phi.T @ (self.model.mass_dof[:, None] * self._phi)
            overlap[np.abs(overlap) < 1e-9] = 0.0
            overlap[~was] = 0.0
            self._q, self._v, self._a = overlap @ self._q, overlap @ self._v, overlap @ self._a
        else:
            self._q = np.zeros(active.size)
            self._v = np.zeros(active.size)
            self._a = np.zeros(active.size)
        self._active, self._target, self._progress = active, target, progress
        self._fading = bool(np.any(progress < 1.0) or np.any(~target))
        self._phi, self._omega2, self._damp = stepped.phi, stepped.omega2, stepped.damping
        self._ops, self._forces = stepped.ops, stepped.forces
        self._update_envelope()

    def _update_envelope(self) -> None:
        self._envelope = 0.5 - 0.5 * np.cos(np.pi * self._progress)
        self._fading_in = self._target & (self._progress < 1.0)

    def _advance_fade(self) -> None:
        """Move every fading mode's progress one step; leaving modes' state follows the
        envelope down to zero (no jump), and modes that reach zero are dropped."""
        step = self.dt / self.transition_s
        old = self._envelope
        self._progress = np.clip(self._progress + np.where(self._target, step, -step), 0.0, 1.0)
        self._update_envelope()
        out = ~self._target
        ratio = np.divide(self._envelope[out], old[out], out=np.zeros(int(out.sum())),
                          where=old[out] > 0.0)
        self._q[out] *= ratio
        self._v[out] *= ratio
        self._a[out] *= ratio
        if np.any(out & (self._progress <= 0.0)):
            self._set_active(self._active[self._target])
        self._fading = bool(np.any(self._progress < 1.0) or np.any(~self._target))

    # -- state ---------------------------------------------------------------------------------
    def reset(self) -> None:
        if self._fading:  # settle the band: every kept mode fully in, none fading out
            kept = self.kept_modes
            self._active = np.empty(0, dtype=np.int64)
            self._set_active(kept)
        self.time = self._t0 = 0.0
        self.steps = 0
        self.diverged = None
        self.set_state(np.zeros(self.model.n_free_dof), np.zeros(self.model.n_free_dof))

    def set_state(self, displacement: np.ndarray, velocity: np.ndarray) -> None:
        """Project a physical state onto the stepped modes (paper eq. 15: ``q = Phi^T M u``)."""
        m = self.model.mass_dof
        if isinstance(self._forces, RefreshedForces):
            self._forces.restart()
        self._q = self._phi.T @ (m * displacement)
        self._v = self._phi.T @ (m * velocity)
        self._a = self._forces(self._q, self.time) - self._damp * self._v

    @property
    def refresh_error(self) -> float | None:
        """Largest measured force error of the refreshed forces since the last state change
        (None when the forces are evaluated on every step)."""
        if isinstance(self._forces, RefreshedForces):
            return self._forces.max_refresh_error
        return None

    @property
    def modal_coordinates(self) -> np.ndarray:
        return self._q.copy()

    def displacement(self) -> np.ndarray:
        return self._phi @ self._q

    def velocity(self) -> np.ndarray:
        return self._phi @ self._v

    def _force(self, q: np.ndarray) -> np.ndarray:
        force = self._forces(q, self.time + self.dt)
        if self._fading:
            # An entering mode takes on its load (all but its own linear restoring force)
            # along its envelope, so it eases into place instead of dropping from rest.
            w = self._envelope
            restoring = -self._omega2 * q
            force = np.where(self._fading_in, restoring + w * (force - restoring), force)
        return force

    def _step_once(self) -> None:
        q1, v1, a1 = self._advance(self._q, self._v, self._a, self._force, self._ops)
        self._q, self._v, self._a = q1, v1, a1
        self._commit()
        if self._fading:
            self._advance_fade()


# ----------------------------------------------------------------------------------------------
# Full physical reference


class PhysicalOperators:
    """``M`` (lumped), ``C`` and ``K`` of the free DOF in physical coordinates.

    Damping is Rayleigh ``alpha M + beta K`` (sparse) when the scene has no modal ratio; with a
    modal ratio ``h`` it is the paper's equivalent ``c = M Phi C Phi^T M`` over every mode, which
    needs the complete (dense) basis.
    """

    def __init__(self, model: MassSpringModel, damping: Damping, dt: float,
                 basis: ModalBasis | None):
        self.m = model.mass_dof
        self.k = model.stiffness_free
        self.dt = dt
        self.damping = damping
        self._modal = None
        self._c = None
        if damping.ratio != 0.0:
            if basis is None or not basis.complete:
                raise ValueError(
                    "full method with a modal damping ratio needs every mode (equivalent "
                    f"damping c = M Phi C Phi^T M); this scene has {model.n_free_dof} free DOF, "
                    "above the dense limit. Use Rayleigh damping (damping.rayleigh) instead.")
            phi = basis.vectors
            cm = damping.modal_coefficients(basis.omega)
            self._modal = (phi, cm, basis.omega)
            # explicit step: (M + dt/2 C)^-1 (f - C v_pred) = M^-1 f - B (dt/2 f + M v_pred)
            # with B = Phi diag(c s) Phi^T, s = 1 / (1 + dt/2 c)  (Phi Phi^T = M^-1 since
            # Phi^T M Phi = I, and s = 1 - dt/2 c s): one n x n product per step
            self._explicit_b = (phi * (cm / (1.0 + 0.5 * dt * cm))[None, :]) @ phi.T
        elif damping.rayleigh_alpha or damping.rayleigh_beta:
            self._c = (sp.diags(damping.rayleigh_alpha * self.m)
                       + damping.rayleigh_beta * self.k).tocsc()
        self._explicit = None
        self._average = None

    def _modal_solve(self, rhs, diag):
        phi = self._modal[0]
        return phi @ ((phi.T @ rhs) / diag)

    def damp(self, v):
        if self._modal is not None:
            phi, cm, _ = self._modal
            return self.m * (phi @ (cm * (phi.T @ (self.m * v))))
        if self._c is not None:
            return self._c @ v
        return 0.0

    def stiff(self, u):
        return self.k @ u

    def explicit_acceleration(self, force, v_pred):
        if self._modal is not None:
            y = force * (0.5 * self.dt)
            y += self.m * v_pred
            a = force / self.m
            a -= self._explicit_b @ y
            return a
        rhs = force - self.damp(v_pred)
        if self._c is None:
            return rhs / self.m
        if self._explicit is None:
            self._explicit = spla.splu((sp.diags(self.m) + 0.5 * self.dt * self._c).tocsc())
        return self._explicit.solve(rhs)

    def solve_average(self, rhs):
        h = 0.5 * self.dt
        if self._modal is not None:
            _, cm, omega = self._modal
            return self._modal_solve(rhs, 1.0 + h * cm + h * h * omega**2)
        if self._average is None:
            a = sp.diags(self.m) + h * h * self.k
            if self._c is not None:
                a = a + h * self._c
            self._average = spla.splu(sp.csc_matrix(a))
        return self._average.solve(rhs)


class FullSimulation(Simulation):
    """Every free DOF in physical coordinates: the reference the modal run is compared with."""

    method = "full"

    def __init__(self, model: MassSpringModel, *, dt: float, integrator: str = "explicit",
                 damping: Damping | None = None, basis: ModalBasis | None = None,
                 strain_limit: float = DEFAULT_STRAIN_LIMIT):
        super().__init__(model, dt=dt, integrator=integrator, damping=damping,
                         strain_limit=strain_limit)
        self.basis = basis
        self._ops = PhysicalOperators(model, self.damping, self.dt, basis)
        self._forces = GeneralizedForces(model, None)
        self.reset()

    def stability_limit(self) -> float:
        if self.basis is None:
            raise ValueError("stability limit needs the modal basis")
        return stable_step_limit(self.basis.omega_max_estimate())

    def reset(self) -> None:
        self.time = self._t0 = 0.0
        self.steps = 0
        self.diverged = None
        n = self.model.n_free_dof
        self.set_state(np.zeros(n), np.zeros(n))

    def set_state(self, displacement: np.ndarray, velocity: np.ndarray) -> None:
        self._u = np.array(displacement, dtype=float)
        self._v = np.array(velocity, dtype=float)
        f = self._forces(self._u, self.time) - self._ops.damp(self._v)
        self._a = f / self.model.mass_dof

    def displacement(self) -> np.ndarray:
        return self._u.copy()

    def velocity(self) -> np.ndarray:
        return self._v.copy()

    def _force(self, u: np.ndarray) -> np.ndarray:
        return self._forces(u, self.time + self.dt)

    def _step_once(self) -> None:
        self._u, self._v, self._a = self._advance(self._u, self._v, self._a, self._force,
                                                  self._ops)
        self._commit()

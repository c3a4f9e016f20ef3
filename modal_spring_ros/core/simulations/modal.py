"""
The paper's method (fig. 5): step only the modes the filter band keeps.

Each step advances the modal coordinates ``q`` (Newmark), maps them to positions
``x = x_rest + Phi_R q`` (fixed particles follow their prescribed motion), evaluates the
nonlinear spring forces and gravity in physical space (eq. 20), projects them back,
``Q = Phi_R^T f``, and solves the uncoupled modal equations ``q'' + C q' = Q``. ``K`` only
gives the basis; the dynamics stay nonlinear. All modes kept = the full run, to round-off.

Changing the band while running is smooth: a mode that leaves the band fades out over
``transition_s`` (a raised-cosine envelope to zero: positions do not jump); a mode that enters
starts from rest and takes on its load along the same envelope, easing into place. Modes not
computed yet are computed when a band first needs them (at most ``max_modes``).

With ``basis_kind="derivatives"`` each band also steps the coordinates it adds
(:mod:`modal_spring_ros.core.bases.derivatives`: the kept modes' second-order response and the
static response to the loads), so that the stream stays right beyond small deformation. Rest
modes and added coordinates are both "coordinates" here, identified by an id: a rest mode by
its index, an added coordinate by an id from :data:`ADDED_ID` up (an
:class:`AddedCoordinateBank` keeps them, per band). A band change fades the leaving band's
added coordinates out and the new ones in, as it does rest modes.

The coordinates stepped and their fade progress are one immutable :class:`ActiveSet`,
replaced whole: a thread that prepares a band switch reads a consistent set, and a reset
during a fade starts from the settled band instead of a half-changed one.
"""
from __future__ import annotations

import dataclasses
import math

from modal_spring_ros.core.bases.basis import ModalBasis, Progress
from modal_spring_ros.core.bases.derivatives import AddedCoordinates
from modal_spring_ros.core.filter_band import BandError, FilterBand
from modal_spring_ros.core.forces import force_model
from modal_spring_ros.core.loads.applied import of_shapes
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.simulations.base import Simulation
from modal_spring_ros.core.simulations.coordinates import (ActiveSet, ADDED_ID,
                                                           AddedCoordinateBank, EMPTY_SET)
from modal_spring_ros.core.simulations.early_step_check import check_step_before_modes, mode_cap
from modal_spring_ros.core.simulations.modal_settings import ModalSettings
from modal_spring_ros.core.simulations.mode_gains import (coordinate_damping, coordinate_gains,
                                                          GainFade)
from modal_spring_ros.core.simulations.prepared_sets import PreparedSets
from modal_spring_ros.core.simulations.step_limits import (check_step, stable_step_limit,
                                                           step_from_limit)
from modal_spring_ros.core.simulations.stepped_set import SteppedSet
import numpy as np


class ModalSimulation(Simulation):
    """
    Steps the modes the filter band keeps, as ``settings`` say (:class:`ModalSettings`).

    ``settings.forces``: how the nonlinear spring forces are evaluated (a force model of
    :data:`~modal_spring_ros.core.forces.FORCES`): every spring on every step, exactly as the
    paper (``exact``); every ``refresh`` steps, continued along the static tangent in between
    (``refreshed``), so that most steps cost nothing per spring; or a sample of the springs
    trained within ``tolerance`` (``sampled``, for a settled band). ``mode_choice``: the
    automatic mode choice that made the run (its ``highest_hz``); ``bank``: the added
    coordinates computed so far (shared by the runs of one basis); ``progress``: told about
    long computations.
    """

    method = 'modal'

    def __init__(self, model: MassSpringModel, basis: ModalBasis, band: FilterBand,
                 settings: ModalSettings, *, mode_choice=None,
                 bank: AddedCoordinateBank | None = None, progress: Progress | None = None):
        super().__init__(model, basis, dt=settings.dt, integrator=settings.integrator,
                         damping=settings.damping, strain_limit=settings.strain_limit)
        #: what the run was built with
        self.settings = settings.validate()
        self.basis_kind = settings.basis_kind
        self._bank = bank if bank is not None else AddedCoordinateBank(
            basis, settings.derivative_directions, progress)
        force_model(settings.forces)  # a known model, options in range
        #: how the spring forces are evaluated
        self.forces = settings.forces
        self.highest_hz = settings.highest_hz
        self._mode_choice = mode_choice
        self.max_modes = mode_cap(basis, settings.max_modes)
        self.transition_s = float(settings.transition_s)
        self._band = band.validate()
        self._set = EMPTY_SET
        self._q = self._v = self._a = np.empty(0)
        self._gains = GainFade(np.ones((2, 0)))
        self._prepared = PreparedSets(self._build_set)
        coordinates = self.coordinates_for(self.select_modes(band))
        if settings.step_share is not None:  # the step from what is stepped: the set built once
            limit = stable_step_limit(float(self._bank.omega(coordinates).max(initial=0.0)))
            self.dt = step_from_limit(limit, settings.step_share, model.scene.name, self.dt)
            self.settings = dataclasses.replace(settings, dt=self.dt, step_share=None)
        self._install(ActiveSet.settled(coordinates), None, self._band)
        self.reset()

    # -- the contract --------------------------------------------------------------------------
    @property
    def kept_modes(self) -> np.ndarray:
        """Return the indices of the rest modes in the band (fading-out modes excluded)."""
        kept = self._set.kept
        return kept[kept < ADDED_ID]

    @property
    def stepped_modes(self) -> np.ndarray:
        """Ids of the coordinates being stepped (the band's, plus those still fading out)."""
        return self._set.modes.copy()

    @property
    def added_coordinates(self) -> AddedCoordinates | None:
        """Return what the band adds to its rest modes (``derivatives`` basis), or None."""
        if self.basis_kind == 'rest':
            return None
        found = self._bank.lookup(self.kept_modes)  # computed when the band was set
        return found[1] if found is not None else None

    @property
    def basis_seconds(self) -> float:
        added = self.added_coordinates
        return self.basis.solve_seconds + (added.seconds if added is not None else 0.0)

    def describe_basis(self) -> str:
        added = self.added_coordinates
        if added is None:
            return f'{self.basis_kind}: {self.kept_modes.size} modes'
        return (f'derivatives: {self.kept_modes.size} modes + {added.derivative_count} '
                f'derivative directions + {added.count - added.derivative_count} static')

    @property
    def coordinates(self) -> int:
        return int(self._set.kept.size)

    @property
    def modes(self) -> int:
        return int(self.kept_modes.size)

    @property
    def fading(self) -> bool:
        return self._set.fading

    @property
    def force_refresh(self) -> int:
        return self.forces.refresh

    @property
    def evaluated_share(self) -> float:
        """Return the share of steps that evaluated the springs exactly so far (1: every one)."""
        return self._forces.evaluated_share

    @property
    def mode_choice(self):
        return self._mode_choice

    def describe_band(self) -> str:
        return self._band.describe()

    def with_dt(self, dt: float) -> 'ModalSimulation':
        settings = dataclasses.replace(self.settings, dt=dt, transition_s=self.transition_s)
        return ModalSimulation(self.model, self.basis, self._band, settings,
                               mode_choice=self._mode_choice, bank=self._bank)

    def omega_max(self) -> float:
        return float(self._bank.omega(self._set.modes).max())

    def coordinates_for(self, keep: np.ndarray) -> np.ndarray:
        """Return the coordinates stepped for rest modes ``keep`` (no state of the run changes)."""
        if self.basis_kind == 'rest':
            return keep
        return np.concatenate([keep, self._bank.for_band(keep)[0]])

    # -- band ----------------------------------------------------------------------------------
    def prepare_band(self, band: FilterBand) -> None:
        """Compute the modes ``band`` needs (the slow part of a band change; no state change)."""
        band.validate()
        limit = min(self.max_modes, self.basis.n_dof)
        top = self.highest_hz if self.highest_hz is not None else math.inf
        if band.by == 'index':
            needed = int(band.top) + 1 if band.bounded_above else limit
            self.basis.ensure_count(min(needed, limit))
            if math.isfinite(top):
                self.basis.ensure_frequency(top, limit)
        elif band.bounded_above or math.isfinite(top):
            self.basis.ensure_frequency(min(band.top if band.bounded_above else top, top), limit)
        else:
            self.basis.ensure_count(limit)

    def select_modes(self, band: FilterBand) -> np.ndarray:
        """
        Return the indices of the computed modes ``band`` keeps (computing what it needs first).

        Changes no state of the run (it checks a band before it is applied).

        :raises BandError: the band keeps no mode.
        """
        self.prepare_band(band)
        f = self.basis.frequencies_hz
        keep = np.flatnonzero(band.keeps(f))
        if band.by == 'index':
            keep = keep[keep < self.max_modes]
        if self.highest_hz is not None:
            keep = keep[f[keep] <= self.highest_hz * (1.0 + 1e-12)]
        if keep.size == 0:
            span = f'{f[0]:.4g} .. {f[-1]:.4g} Hz' if band.by == 'hz' else f'0 .. {f.size - 1}'
            raise BandError(f'filter band {band.describe()} keeps no mode '
                            f'(the computed modes span {span})')
        return keep.astype(np.int64)

    def set_band(self, band: FilterBand, transition_s: float | None = None) -> None:
        """Change the band; leaving coordinates fade out, entering ones start from rest."""
        keep = self.coordinates_for(self.select_modes(band))
        transition = self.transition_s if transition_s is None else float(transition_s)
        self._install(self._set.switched(keep, transition <= 0.0), self._set, band,
                      transition <= 0.0)
        self.transition_s = transition
        self._band = band

    @property
    def truncated(self) -> bool:
        """Tell whether the band reaches past the computed modes (capped at ``max_modes``)."""
        top = self.highest_hz if self.highest_hz is not None else math.inf
        band = self._band
        edge = min(band.top if band.bounded_above and band.by == 'hz' else math.inf, top)
        return not self.basis.complete and self.basis.frequencies_hz[-1] <= edge

    def check_band(self, band: FilterBand, dt_name: str = 'dt') -> np.ndarray:
        """
        Return the coordinates stepped for ``band``, if this run can step them (computed first).

        :raises BandError: it keeps no mode.
        :raises UnstableStepError: its highest mode is unstable at ``dt`` (explicit).
        """
        check_step_before_modes(self.basis, band, dt=self.dt, integrator=self.integrator,
                                highest_hz=self.highest_hz, max_modes=self.max_modes,
                                method=self.method, dt_name=dt_name)
        coordinates = self.coordinates_for(self.select_modes(band))
        omega = self._bank.omega(coordinates)
        check_step(self.integrator, self.dt, float(omega.max()), self.method, dt_name)
        return coordinates

    def prepare_switch(self, band: FilterBand, transition_s: float | None = None,
                       dt_name: str = 'dt') -> None:
        """Build the operators of the modes stepped during the transition and after it."""
        keep = self.check_band(band, dt_name)
        instant = (self.transition_s if transition_s is None else transition_s) <= 0.0
        current = self._set  # one consistent snapshot
        self._prepared.prepare(self.basis.count, current.next_modes(keep, instant),
                               instant or not current.modes.size, band.damping)
        self._prepared.prepare(self.basis.count, keep, True, band.damping)

    def _build_set(self, modes: np.ndarray, settled: bool,
                   damping: tuple[str, ...]) -> SteppedSet:
        """
        Build the operators of stepping ``modes`` (forces trained for a settled band only).

        A fade is short: training for it would cost more than it saves.
        """
        forces = self.forces
        if not settled and force_model(forces).trained:
            forces = forces.untrained()
        ratios = coordinate_damping(damping, modes, self.basis.frequencies_hz)
        return SteppedSet.build(self.model, self._bank, modes, self.damping, forces, self.dt,
                                self.strain_limit, ratios)

    def _install(self, new: ActiveSet, old: ActiveSet | None, band: FilterBand,
                 instant: bool = False) -> None:
        """
        Step ``new`` from now on, with ``band``'s gains and damping.

        With ``old``, coordinates in both sets keep their state and those new to the set start from
        rest (a dropped one has faded to zero), and the gains fade to ``band``'s (``instant``:
        at once); without, it starts at zero. Built first, assigned last: a failure changes
        nothing.
        """
        stepped = self._prepared.take(self.basis.count, new.modes, not new.fading, band.damping)
        gains = coordinate_gains(band, new.modes, self.basis.frequencies_hz)
        q, v, a = (np.zeros(new.modes.size) for _ in range(3))
        if old is not None and old.modes.size:
            kept = np.isin(new.modes, old.modes)
            where = np.searchsorted(old.modes, new.modes[kept])
            q[kept], v[kept], a[kept] = self._q[where], self._v[where], self._a[where]
        self._phi, self._omega2, self._damp = stepped.phi, stepped.omega2, stepped.damping
        self._ops, self._forces, self._frame = stepped.ops, stepped.forces, stepped.frame
        self._frame_shapes = stepped.frame_shapes
        self._q, self._v, self._a = q, v, a
        self._gains.retarget(self._set.modes, new.modes, gains,
                             instant or old is None or self.transition_s <= 0.0)
        self._set = new
        self._update_envelope()

    def _update_envelope(self) -> None:
        s = self._set
        self._envelope = 0.5 - 0.5 * np.cos(np.pi * s.progress)
        self._fading_in, self._is_fading = s.target & (s.progress < 1.0), s.fading

    def _advance_fade(self) -> None:
        """
        Move every fading mode's progress one step (leaving ones' state follows it, no jump).

        Modes whose envelope reaches zero are dropped.
        """
        s = self._set
        step = self.dt / self.transition_s
        old = self._envelope
        progress = np.clip(s.progress + np.where(s.target, step, -step), 0.0, 1.0)
        self._set = ActiveSet(s.modes, s.target, progress)
        self._update_envelope()
        out = ~s.target
        ratio = np.divide(self._envelope[out], old[out], out=np.zeros(int(out.sum())),
                          where=old[out] > 0.0)
        self._q[out] *= ratio
        self._v[out] *= ratio
        self._a[out] *= ratio
        if np.any(out & (progress <= 0.0)):
            self._install(self._set.switched(self._set.kept, False), self._set, self._band)

    # -- state ---------------------------------------------------------------------------------
    def reset(self) -> None:
        if self._set.fading or self._gains.fading:  # settle: kept modes fully in, gains reached
            self._install(ActiveSet.settled(self._set.kept), None, self._band)
        self._at_rest()

    def set_state(self, displacement: np.ndarray, velocity: np.ndarray) -> None:
        """Project a physical state onto the stepped modes (paper eq. 15: ``q = Phi^T M u``)."""
        m = self.model.mass_dof
        self._forces.restart()
        self._q = self._phi.T @ (m * displacement)
        self._v = self._phi.T @ (m * velocity)
        self._a = self._driven_force(self._q, self._v, self.time) - self._damp * self._v

    @property
    def modal_coordinates(self) -> np.ndarray:
        return self._q.copy()

    def displacement(self) -> np.ndarray:
        return self._phi @ self._q

    def shown_displacement(self) -> np.ndarray:
        if self._gains.unit_output:
            return self.displacement()
        return self._phi @ (self._gains.now[0] * self._q)

    def _frame_coordinates(self) -> tuple[np.ndarray, np.ndarray]:
        q = self._q if self._gains.unit_output else self._gains.now[0] * self._q
        return self._frame_shapes, q.astype(np.float32)

    def velocity(self) -> np.ndarray:
        return self._phi @ self._v

    def motion_size(self) -> tuple[float, float]:  # mass-orthonormal coordinates: q^T q = u^T M u
        return math.sqrt(self._q @ self._q), math.sqrt(self._v @ self._v)

    @property
    def _last_max_strain(self) -> float:
        return self._forces.last_max_strain

    def _force(self, q: np.ndarray) -> np.ndarray:
        # The Coriolis load depends on the velocity: like damping in the explicit step, it is
        # taken at the predicted velocity v + dt/2 a.
        v = self._v + (0.5 * self.dt) * self._a if self._frame is not None else self._v
        force = self._driven_force(q, v, self._ending)
        if self._is_fading:
            # An entering mode takes on its load (all but its own linear restoring force)
            # along its envelope, so it eases into place instead of dropping from rest.
            restoring = -self._omega2 * q
            w = self._envelope
            force = np.where(self._fading_in, restoring + w * (force - restoring), force)
        return force

    def _driven_force(self, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """
        Return the generalised force at ``q``, ``v``, ``t``, each coordinate's loads gained.

        The loads drive the object from outside (gravity, the clamp's inertial loads, applied
        loads); the springs' force, nonlinear part included, is never gained: that would change
        the stiffness about a deformed shape (above 1, turn it negative: a run that diverges).
        """
        force = self._forces(q, t)
        driven = None
        loaded = self._applied(of_shapes(self._phi, q), t) if self.loads else None
        if loaded is not None:
            driven = loaded[1] @ self._phi[loaded[0]]
        if self._frame is not None:
            coupling = self._frame.coupling(q, v, t)
            driven = coupling if driven is None else driven + coupling
        if driven is not None:
            force += driven
        if not self._gains.unit_load:
            loads = self._forces.loads(t)
            force += (self._gains.now[1] - 1.0) * (loads if driven is None else loads + driven)
        return force

    def _step_once(self) -> None:
        q1, v1, a1 = self._advance(self._q, self._v, self._a, self._force, self._ops)
        self._q, self._v, self._a = q1, v1, a1
        self._commit()
        if self._is_fading:
            self._advance_fade()
        if self._gains.fading:
            self._gains.advance(self.dt / self.transition_s)

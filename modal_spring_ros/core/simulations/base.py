"""
The simulation contract: what every method offers its callers.

A :class:`Simulation` steps one scene at a fixed ``dt`` with one integrator and reports its
state in physical terms. Every method has a filter band (a full run keeps it for a later switch
to a modal run: every mode takes part in it), kept modes, force options, a refresh error and a
:class:`SimulationStatus` for diagnostics, so callers never ask which method they hold.

Every step detects divergence on the step it happens (a non-finite state, a spring strained
beyond ``strain_limit``, or an implicit step that does not converge), raises
:class:`DivergenceError` and keeps the last good state, so no caller ever sees NaN.
"""
from __future__ import annotations

import abc
import dataclasses
import math
from typing import Callable, ClassVar

from modal_spring_ros.core.bases.basis import ModalBasis
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.forces import ForceModel, ForceOptions, ForceReport
from modal_spring_ros.core.forces.exact import EXACT_REPORT
from modal_spring_ros.core.integrators import Integrator, stable_step
from modal_spring_ros.core.integrators import integrator as make_integrator
from modal_spring_ros.core.integrators import NonConvergence, Operators
from modal_spring_ros.core.loads.applied import applied_loads, of_vector, stepped_loads
from modal_spring_ros.core.loads.contact import contact_load, ContactLoad
from modal_spring_ros.core.loads.holder import LoadHolder
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.model.scene import Damping
from modal_spring_ros.core.simulations.step_limits import check_step, MIN_DT_S, stable_step_limit
from modal_spring_ros.core.threads import stepping_threads
import numpy as np

#: Default spring strain treated as divergence (the simulation has left any meaningful regime).
DEFAULT_STRAIN_LIMIT = 1.0


class DivergenceError(RuntimeError):
    """The step diverged. The simulation keeps its last good state."""

    def __init__(self, reason: str, time: float, step: int):
        super().__init__(f'diverged at t = {time:.6g} s (step {step}): {reason}')
        self.reason, self.time, self.step = reason, time, step


@dataclasses.dataclass(frozen=True)
class SimulationStatus:
    """What a simulation reports about itself (plain values, for diagnostics and summaries)."""

    method: str
    band: str                  # the band stepped, as text ("full" for a full run)
    basis: str                 # what the coordinates are ("derivatives: 15 modes + ...")
    basis_seconds: float       # time spent computing them (modes and what a band adds), s
    modes: int                 # rest modes of the band (modal) or free DOF (full) stepped
    coordinates: int           # every coordinate stepped (modal: modes and what they add)
    modes_computed: int
    mode_choice: str           # the automatic mode choice, or "off"
    integrator: str
    dt: float
    force_refresh: int         # steps between exact spring-force evaluations (configured)
    stability_limit: float     # explicit limit of the coordinates stepped, s
    time: float
    steps: int
    max_strain: float
    fading: bool               # a band change is still fading modes in or out
    forces: ForceReport = EXACT_REPORT  # how the spring forces were evaluated
    measured: str = 'off'              # what the automatic choice's pilot measured, and how
    contacts: str = 'no colliders'     # particles touching the scene's colliders, deepest


class Simulation(LoadHolder, abc.ABC):
    """What every method shares: time, state in physical terms, band, divergence checks."""

    #: registry name
    method: ClassVar[str]
    #: how the spring forces are evaluated (a full run: every spring on every step)
    forces: ForceOptions = ForceOptions()
    #: the force model of the coordinates stepped, set by each method
    _forces: ForceModel

    def __init__(self, model: MassSpringModel, basis: ModalBasis | None, *, dt: float,
                 integrator: str, damping: Damping | None, strain_limit: float):
        if not (math.isfinite(dt) and dt >= MIN_DT_S):
            raise ValueError(f'dt ({dt}) must be a finite number of seconds, at least '
                             f'{MIN_DT_S:g} s (a smaller step does not advance time)')
        self._integrator: Integrator = make_integrator(integrator)
        self.model, self.basis, self.dt, self.integrator = model, basis, float(dt), integrator
        self.damping = model.scene.damping if damping is None else damping
        self.strain_limit = float(strain_limit)
        self.time, self.steps, self._t0, self.last_iterations = 0.0, 0, 0.0, 1
        self._evaluations = 0     # force evaluations of the steps counted in ``steps``
        self.diverged: DivergenceError | None = None
        self.loads, self.frame_poses = {}, {}

    # -- what every method offers --------------------------------------------------------------
    #: the filter band, set by each method's constructor and by :meth:`set_band`
    _band: FilterBand
    #: what the automatic choice's pilot run measured (:class:`~modal_spring_ros.core.auto.plan.
    #: PilotReport`), on a run it chose; None otherwise
    pilot = None
    #: what the run is watched against while it runs (:class:`~modal_spring_ros.core.auto.
    #: watch.windows.WatchReference`), on a run the automatic choice chose; None otherwise
    watch_reference = None

    @property
    def evaluations_per_step(self) -> float:
        """Return the force evaluations a step has made (before any: the integrator's own)."""
        return (self._evaluations / self.steps if self.steps
                else float(self._integrator.evaluations_per_step))

    @property
    def band(self) -> FilterBand:
        """Filter band stepped (a full run keeps it for a switch to a modal run)."""
        return self._band

    @property
    @abc.abstractmethod
    def kept_modes(self) -> np.ndarray:
        """Return the indices of the modes that take part (a full run: every one computed)."""

    @property
    def force_refresh(self) -> int:
        """Step between exact evaluations of the nonlinear spring forces."""
        return 1

    @property
    def mode_choice(self):
        """Return the automatic mode choice (a ``ModeChoice``) of this run's modes, or None."""
        return None

    @property
    def fading(self) -> bool:
        """Tell whether a band change is still fading modes in or out."""
        return False

    def force_report(self) -> ForceReport:
        """Return how the spring forces are evaluated, their measured error, a fallback."""
        return self._forces.report()

    @property
    def truncated(self) -> bool:
        """Tell whether the band reaches past the modes computed (capped at ``max_modes``)."""
        return False

    @property
    @abc.abstractmethod
    def coordinates(self) -> int:
        """Return the number of coordinates stepped (modes and what the band adds, or free DOF)."""

    @property
    def modes(self) -> int:
        """Return the number of rest modes of the band stepped (a full run: its free DOF)."""
        return self.coordinates

    @abc.abstractmethod
    def describe_band(self) -> str:
        """Return the band stepped, as text."""

    def describe_basis(self) -> str:
        """Return what the coordinates stepped are, as text."""
        return 'physical: every free DOF'

    @property
    def basis_seconds(self) -> float:
        """Time spent computing the basis of the coordinates stepped, s."""
        return self.basis.solve_seconds if self.basis is not None else 0.0

    @abc.abstractmethod
    def set_band(self, band: FilterBand, transition_s: float | None = None) -> None:
        """Change the filter band (see each method)."""

    @abc.abstractmethod
    def prepare_switch(self, band: FilterBand, transition_s: float | None = None,
                       dt_name: str = 'dt') -> None:
        """
        Check ``band`` and do the slow part of switching to it ahead, from any thread.

        (Computing the modes it needs, building operators) while the run goes on, changing none
        of its state; :meth:`set_band` then finds the work done.

        :raises BandError: the band keeps no mode.
        :raises UnstableStepError: its highest mode is unstable at this ``dt`` (explicit), named
            ``dt_name`` in the message.
        """

    def check_stable(self, dt_name: str = 'dt') -> None:
        """Refuse a step at or above the integrator's limit for the coordinates stepped."""
        check_step(self.integrator, self.dt, self.omega_max(), self.method, dt_name)

    @abc.abstractmethod
    def with_dt(self, dt: float) -> 'Simulation':
        """Return the same settings with another step, at rest at t = 0."""

    def status(self) -> SimulationStatus:
        choice = self.mode_choice
        return SimulationStatus(
            method=self.method, band=self.describe_band(), basis=self.describe_basis(),
            basis_seconds=self.basis_seconds, modes=self.modes, coordinates=self.coordinates,
            modes_computed=self.basis.count if self.basis is not None else 0,
            mode_choice=choice.describe() if choice is not None else 'off',
            integrator=self.integrator, dt=self.dt, force_refresh=self.force_refresh,
            stability_limit=self.stability_limit(),
            time=self.time, steps=self.steps, max_strain=self.max_strain(),
            fading=self.fading, forces=self.force_report(),
            measured=self.pilot.describe() if self.pilot is not None else 'off',
            contacts=self.describe_contacts())

    # -- state in physical terms ---------------------------------------------------------------
    @abc.abstractmethod
    def displacement(self) -> np.ndarray:
        """Return the free-DOF displacement ``u`` from rest in the clamp's frame (flat)."""

    def shown_displacement(self) -> np.ndarray:
        """Return the displacement streamed: :meth:`displacement` with the output gains."""
        return self.displacement()

    @abc.abstractmethod
    def velocity(self) -> np.ndarray:
        """Free-DOF velocity in the clamp's frame (flat)."""

    @abc.abstractmethod
    def omega_max(self) -> float:
        """Return the highest angular frequency among the coordinates this run steps, rad/s."""

    def stability_limit(self) -> float:
        """Return the explicit step's limit for the coordinates this run steps, s."""
        return stable_step_limit(self.omega_max())

    @abc.abstractmethod
    def reset(self) -> None:
        """Back to the rest shape, at rest, at t = 0 (the band settled: nothing fading)."""

    @abc.abstractmethod
    def set_state(self, displacement: np.ndarray, velocity: np.ndarray) -> None:
        """Start from a free-DOF displacement and velocity (relative to the base)."""

    def _at_rest(self) -> None:
        """
        Back to rest at t = 0.

        No pull, and a clamp with a state of its own restarted (not on construction: a simulation
        rebuilt for other settings takes the clamp over).
        """
        if self.time or self.steps:
            self.model.restart_clamp()
        self.time = self._t0 = 0.0
        self.steps = self._evaluations = 0
        self.diverged = None
        placed = self.loads.get(ContactLoad.name)     # colliders stay where they were put
        self.loads = {k: v.placed_as(placed) for k, v in self._scene_loads().items()}
        n = self.model.n_free_dof
        self.set_state(np.zeros(n), np.zeros(n))

    def positions(self) -> np.ndarray:
        """Return the particles' (n, 3) positions, in scene order."""
        x = self.model.positions(self.shown_displacement(), self.time)
        return self.model.positions3(x)

    def movement_into(self, out: np.ndarray) -> None:
        """
        Write each particle's movement from its rest position in the world into ``out``.

        ``out``: (3, n) float32, C-contiguous, one row per world axis (a cloud's
        :attr:`~modal_spring_ros.bags.messages.pointcloud.CloudBuffer.movement`). A run that
        keeps its shapes for frames (:meth:`_frame_coordinates`) and whose clamp only translates
        writes it with one product in float32, with no array per frame.
        """
        frame = None if self.model.rotates else self._frame_coordinates()
        if frame is None:
            out[...] = (self.positions() - self.model.scene.rest_positions).T
        else:
            shapes, q = frame
            self.model.write_movement(out, shapes, q, self.time)

    def _frame_coordinates(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Return the frame shapes and float32 coordinates shown (None: the run has none)."""
        return None

    def energy(self) -> dict[str, float]:
        u = self.displacement()
        x = self.model.positions(u, self.time)
        return self.model.energy(x, self.model.world_velocity(u, self.velocity(), self.time))

    def max_strain(self) -> float:
        return self.model.max_strain(self.model.positions(self.displacement(), self.time))

    def motion_size(self) -> tuple[float, float]:
        """Return the state's mass-weighted sizes ``sqrt(u^T M u)``, ``sqrt(v^T M v)``."""
        m, u, v = self.model.mass_dof, self.displacement(), self.velocity()
        return math.sqrt(u @ (m * u)), math.sqrt(v @ (m * v))

    def take_over(self, other: 'Simulation') -> None:
        """Continue from another simulation's physical state and time (a settings change)."""
        self._t0, self.steps, self.time, self._evaluations = other.time, 0, other.time, 0
        self.loads = {**other.loads, **self._scene_loads(other.loads.get(ContactLoad.name))}
        self.frame_poses = other.frame_poses
        self.set_state(other.displacement(), other.velocity())

    def _scene_loads(self, contact: ContactLoad | None = None) -> dict:
        """Return the loads the scene itself brings (its contact, tuned to this run's step)."""
        if self.model.scene.contact is None:
            return {}
        return {ContactLoad.name: contact_load(self.model, self.model.scene.contact, self.dt,
                                               self.penalty_limit(), contact)}

    def penalty_limit(self) -> float:
        """Return the run's own integrator's step limit (inf: implicit) a penalty is tuned to."""
        return (stable_step(self.integrator, self.omega_max()) if self.basis is not None
                else math.inf)

    def _applied(self, displacement: Callable[[np.ndarray], np.ndarray], t: float,
                 in_world: bool = False) -> tuple[np.ndarray, np.ndarray] | None:
        """(free-DOF indices, forces) of every load at ``t``, or None."""
        return applied_loads(self.model, self.loads, displacement, t, in_world)

    # -- stepping ------------------------------------------------------------------------------
    def step(self, count: int = 1) -> None:
        """
        Advance ``count`` steps. Raises :class:`DivergenceError` (state kept at last good).

        On one BLAS thread (:func:`~modal_spring_ros.core.threads.stepping_threads`; a caller
        stepping one at a time holds it around its loop).
        """
        with stepping_threads():
            for _ in range(count):
                self._step_once()

    @abc.abstractmethod
    def _step_once(self) -> None:
        ...

    @property
    @abc.abstractmethod
    def _last_max_strain(self) -> float:
        """Largest spring strain of the last force evaluation."""

    def _advance(self, u, v, a, force: Callable[[np.ndarray], np.ndarray], ops: Operators):
        """One integrator step in whatever coordinates ``u`` is; checks, does not commit."""
        try:
            u1, v1, a1, self.last_iterations = self._integrator.step(u, v, a, self.dt, force,
                                                                     ops)
        except NonConvergence as exc:
            self.diverged = DivergenceError(str(exc), self._ending, self.steps + 1)
            raise self.diverged from None
        self._checked(a1)
        return u1, v1, a1

    @property
    def _ending(self) -> float:
        """Return the time the step under way ends at, as :meth:`_commit` sets it (to the bit)."""
        return self._t0 + (self.steps + 1) * self.dt

    def _checked(self, a1: np.ndarray) -> None:
        """Check a step for divergence (a finite ``a1``: ``u1``, ``v1`` derive from it)."""
        reason = None
        if not math.isfinite(float(a1 @ a1)):
            reason = 'non-finite state'
        elif self._last_max_strain > self.strain_limit:
            reason = (f'spring strain {self._last_max_strain:.3g} exceeds the limit '
                      f'{self.strain_limit:g}')
        if reason is not None:
            self.diverged = DivergenceError(reason, self._ending, self.steps + 1)
            raise self.diverged

    def _commit(self) -> None:
        self.time = self._ending
        self.steps += 1
        self._evaluations += self.last_iterations
        self.diverged = None
        if any(load.keeps_state for load in self.loads.values()):
            u = self.displacement()
            self.loads = stepped_loads(self.model, self.loads, of_vector(u), self.time)

"""
The full physical reference: every free DOF in physical coordinates.

Steps the same nonlinear forces with the same integrators and the equivalent damping; it is
what modal runs are compared with. With every mode kept, the two agree to round-off.
"""
from __future__ import annotations

from modal_spring_ros.core.bases.basis import ModalBasis
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.forces.exact import ExactForces
from modal_spring_ros.core.integrators.base import ROUNDOFF_SHARE
from modal_spring_ros.core.model.definite_factor import factor_definite
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.model.scene import Damping
from modal_spring_ros.core.simulations.base import (DEFAULT_STRAIN_LIMIT, Simulation,
                                                    stable_step_limit)
from modal_spring_ros.core.simulations.modal import ModalSimulation
from modal_spring_ros.core.simulations.modal_settings import ModalSettings
from modal_spring_ros.core.simulations.world_frame import WorldFrameRun
import numpy as np
import scipy.sparse as sp


class PhysicalOperators:
    """
    ``M`` (lumped), ``C`` and ``K`` of the free DOF in physical coordinates.

    Damping is Rayleigh ``alpha M + beta K`` (sparse) when the scene has no modal ratio; with a
    modal ratio ``h`` it is the paper's equivalent ``c = M Phi C Phi^T M`` over every mode, which
    needs the complete (dense) basis.
    """

    def __init__(self, model: MassSpringModel, damping: Damping, dt: float,
                 basis: ModalBasis | None):
        self.m = model.mass_dof
        self.k = model.stiffness_free
        self.points = model.free_points  # the factors' ordering
        self.acceleration_floor = ROUNDOFF_SHARE * float(
            np.max(np.abs(model.gravity_force / self.m), initial=0.0))
        self.dt = dt
        self.damping = damping
        self._modal = None
        self._c = None
        if damping.ratio != 0.0:
            if basis is None or not basis.complete:
                raise ValueError(
                    'full method with a modal damping ratio needs every mode (equivalent '
                    f'damping c = M Phi C Phi^T M); this scene has {model.n_free_dof} free DOF, '
                    'above the dense limit. Use Rayleigh damping (damping.rayleigh) instead.')
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
            self._explicit = factor_definite(sp.diags(self.m) + 0.5 * self.dt * self._c,
                                             points=self.points)
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
            self._average = factor_definite(a, points=self.points)
        return self._average.solve(rhs)


class FullSimulation(Simulation):
    """
    Every free DOF in physical coordinates: the reference the modal run is compared with.

    Every mode takes part, so the band has no effect on it; it is kept (``set_band``) so that a
    switch to the modal method starts with the band the user chose.
    """

    method = 'full'

    def __init__(self, model: MassSpringModel, basis: ModalBasis | None = None,
                 band: FilterBand = FilterBand(), *, dt: float, integrator: str = 'explicit',
                 damping: Damping | None = None, strain_limit: float = DEFAULT_STRAIN_LIMIT):
        super().__init__(model, basis, dt=dt, integrator=integrator, damping=damping,
                         strain_limit=strain_limit)
        self._band = band
        self._probe: ModalSimulation | None = None  # checks bands for a later modal run
        self._ops = PhysicalOperators(model, self.damping, self.dt, basis)
        # a turning clamp: world coordinates, the clamp prescribed (see world_frame)
        self._world = WorldFrameRun(model, self._ops) if model.rotates else None
        self._forces = self._world.forces if self._world else ExactForces(model, None)
        self.reset()

    @property
    def kept_modes(self) -> np.ndarray:
        """Every mode takes part in a full run: the indices of those computed."""
        return np.arange(self.basis.count if self.basis is not None else 0, dtype=np.int64)

    @property
    def coordinates(self) -> int:
        return self.model.n_free_dof

    def describe_band(self) -> str:
        return 'full'

    def set_band(self, band: FilterBand, transition_s: float | None = None) -> None:
        self._band = band.validate()

    def prepare_switch(self, band: FilterBand, transition_s: float | None = None,
                       dt_name: str = 'dt') -> None:
        """Check that the band is one a modal run of this step could take over."""
        if self._probe is None:
            self._probe = ModalSimulation(self.model, self.basis, FilterBand(),
                                          ModalSettings(dt=self.dt, integrator=self.integrator,
                                                        strain_limit=self.strain_limit))
        self._probe.check_band(band, dt_name)

    def with_dt(self, dt: float) -> 'FullSimulation':
        return FullSimulation(self.model, self.basis, self._band, dt=dt,
                              integrator=self.integrator, damping=self.damping,
                              strain_limit=self.strain_limit)

    def stability_limit(self) -> float:
        if self.basis is None:
            raise ValueError('stability limit needs the modal basis')
        return stable_step_limit(self.basis.omega_max_estimate())

    def reset(self) -> None:
        self._at_rest()

    def set_state(self, displacement: np.ndarray, velocity: np.ndarray) -> None:
        u = np.array(displacement, dtype=float)
        v = np.array(velocity, dtype=float)
        if self._world is not None:
            u, v = self._world.to_world(u, v, self.time)
            f = self._world.force(u, self.time) - self._world.damp(v)
        else:
            f = self._forces(u, self.time) - self._ops.damp(v)
        self._u, self._v, self._a = u, v, f / self.model.mass_dof

    def displacement(self) -> np.ndarray:
        if self._world is not None:
            return self._world.to_frame(self._u, self._v, self.time)[0]
        return self._u.copy()

    def velocity(self) -> np.ndarray:
        if self._world is not None:
            return self._world.to_frame(self._u, self._v, self.time)[1]
        return self._v.copy()

    @property
    def _last_max_strain(self) -> float:
        return self._forces.last_max_strain

    def _force(self, u: np.ndarray) -> np.ndarray:
        t = self.time + self.dt
        force = (self._world.force(u, t) if self._world is not None else self._forces(u, t))
        if self.pull is not None or self.wrench is not None:
            # world coordinates (a turning clamp stepped in the world): the loads' own forces
            loaded = self._applied(lambda dofs: u[dofs], t, in_world=self._world is not None)
            if loaded is not None:
                np.add.at(force, loaded[0], loaded[1])
        return force

    def _step_once(self) -> None:
        ops = self._ops if self._world is None else self._world.at(self.time + self.dt)
        self._u, self._v, self._a = self._advance(self._u, self._v, self._a, self._force, ops)
        self._commit()

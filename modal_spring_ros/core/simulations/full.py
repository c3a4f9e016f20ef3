"""
The full physical reference: every free DOF in physical coordinates.

Steps the same nonlinear forces with the same integrators and the equivalent damping; it is
what modal runs are compared with. With every mode kept, the two agree to round-off.
"""
from __future__ import annotations

from typing import NamedTuple

from modal_spring_ros.core.bases.basis import ModalBasis
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.forces.exact import ExactForces
from modal_spring_ros.core.integrators.base import ROUNDOFF_SHARE
from modal_spring_ros.core.loads.applied import of_vector
from modal_spring_ros.core.model.definite_factor import factor_definite
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.model.scene import Damping
from modal_spring_ros.core.simulations.base import DEFAULT_STRAIN_LIMIT, Simulation
from modal_spring_ros.core.simulations.modal import ModalSimulation
from modal_spring_ros.core.simulations.modal_settings import ModalSettings
from modal_spring_ros.core.simulations.world_frame import WorldFrameRun
import numpy as np
import scipy.sparse as sp


#: Lowest modes a full run of a scene too large for every mode damps exactly by its modal
#: ratio; beyond them the ratio's mass-proportional match at the highest of them takes over.
RATIO_MODES = 32


class DampingEntries(NamedTuple):
    """
    Entries an explicit full step multiplies for its damping, beyond the springs' forces.

    ``dense``: of the n x n matrix of a modal ratio over every mode; ``low_rank``: of the
    products with the lowest modes' ``n x k`` shapes (a ratio on a scene too large for every
    mode); ``stiffness``: stored entries of ``K``, once per product with ``beta K`` and solve
    with the factor of ``M + dt/2 C`` (a stiffness-proportional term).
    """

    dense: int = 0
    low_rank: int = 0
    stiffness: int = 0


class PhysicalOperators:
    """
    ``M`` (lumped), ``C`` and ``K`` of the free DOF in physical coordinates.

    Damping is Rayleigh ``alpha M + beta K`` (sparse) when the scene has no modal ratio. With a
    modal ratio ``h`` it is the paper's equivalent ``c = M Phi C Phi^T M``: over every mode
    where the scene is small enough for the complete (dense) basis; otherwise over its lowest
    ``RATIO_MODES`` modes (which carry the motion), with a mass-proportional term
    ``2 h omega_k M`` beyond them (exact at the highest of them, ``h omega_k / omega`` above:
    never more than ``h``, so it costs the explicit step nothing), the scene's Rayleigh terms
    added: ``C = (alpha + 2 h omega_k) M + beta K + M Phi_k D Phi_k^T M`` with ``D`` what makes
    each of the ``k`` modes' damping exactly ``2 h omega_i + alpha + beta omega_i^2``. Its
    solves are the Rayleigh ones with a rank-``k`` correction (Woodbury).
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
        self._low = None          # (U = M Phi_k, D): the rank-k part of a ratio's damping
        alpha, beta = damping.rayleigh_alpha, damping.rayleigh_beta
        if damping.ratio != 0.0 and basis is not None and basis.complete:
            phi = basis.vectors
            cm = damping.modal_coefficients(basis.omega)
            self._modal = (phi, cm, basis.omega)
            self._explicit_b = None          # made at the first explicit step
            self._damping_matrix = None      # made once it pays (``damp``)
            self._damped = 0                 # products with C made without it
            return
        if damping.ratio != 0.0:
            if basis is None:
                raise ValueError('full method with a modal damping ratio needs the modes it '
                                 'damps (a basis)')
            count = min(RATIO_MODES, basis.n_dof - 2)
            basis.ensure_count(count)
            phi, omega = basis.vectors[:, :count], basis.omega[:count]
            tail = 2.0 * damping.ratio * float(omega[-1])
            alpha += tail
            self._low = (self.m[:, None] * phi,
                         damping.modal_coefficients(omega) - alpha - beta * omega ** 2)
        if alpha or beta:
            self._c = (sp.diags(alpha * self.m) + beta * self.k).tocsc()
        self._mass_only = not beta       # (M + x C_rayleigh) is diagonal
        self._alpha = alpha
        self._explicit = None
        self._average = None

    def explicit_entries(self, turning: bool = False) -> DampingEntries:
        """
        Return what an explicit step multiplies for its damping (:class:`DampingEntries`).

        ``turning``: the run steps in the world frame of a turning clamp, and damps its frame's
        velocity too (one more product with ``C`` a step).
        """
        n = self.m.size
        if self._modal is not None:   # B (dt/2 f + M v): one n x n product; C v: one more
            return DampingEntries(dense=n * n * (2 if turning else 1))
        # U^T v and U (D ...) in the damping, two more in the Woodbury solve
        k = self._low[1].size if self._low is not None else 0
        # C v and a solve with the factor of M + dt/2 C (not diagonal where C has beta K)
        stiffness = 0 if self._mass_only else self.k.nnz
        return DampingEntries(low_rank=(6 if turning else 4) * n * k,
                              stiffness=stiffness * (2 if turning else 1))

    def _modal_solve(self, rhs, diag):
        phi = self._modal[0]
        return phi @ ((phi.T @ rhs) / diag)

    def damp(self, v):
        if self._modal is not None:
            if self._damping_matrix is None:
                # C = M Phi diag(c) Phi^T M, one product where the shapes take two: made once it
                # pays (making it costs about n of the products it halves), as a turning
                # clamp's run damps its frame's velocity every step; a state set once never does
                phi, cm, _ = self._modal
                self._damped += 1
                if self._damped < self.m.size:
                    return self.m * (phi @ (cm * (phi.T @ (self.m * v))))
                self._damping_matrix = (self.m[:, None] * phi * cm[None, :]) @ (
                    phi.T * self.m[None, :])
            return self._damping_matrix @ v
        out = self._c @ v if self._c is not None else 0.0
        if self._low is not None:
            u, d = self._low
            out = out + u @ (d * (u.T @ v))
        return out

    def stiff(self, u):
        return self.k @ u

    def explicit_acceleration(self, force, v_pred):
        if self._modal is not None:
            y = force * (0.5 * self.dt)
            y += self.m * v_pred
            a = force / self.m
            if self._explicit_b is None:
                # explicit step: (M + dt/2 C)^-1 (f - C v_pred) = M^-1 f - B (dt/2 f + M v_pred)
                # with B = Phi diag(c s) Phi^T, s = 1 / (1 + dt/2 c)  (Phi Phi^T = M^-1 since
                # Phi^T M Phi = I, and s = 1 - dt/2 c s): one n x n product per step, the
                # matrix made once per run (a run built only to be re-stepped never makes it)
                phi, cm, _ = self._modal
                self._explicit_b = (phi * (cm / (1.0 + 0.5 * self.dt * cm))[None, :]) @ phi.T
            a -= self._explicit_b @ y
            return a
        rhs = force - self.damp(v_pred)
        if self._c is None:
            return rhs / self.m
        if self._explicit is None:
            self._explicit = self._solver(
                sp.diags(self.m) + 0.5 * self.dt * self._c,
                (1.0 + 0.5 * self.dt * self._alpha) * self.m if self._mass_only else None)
        return self._explicit(rhs)

    def solve_average(self, rhs):
        h = 0.5 * self.dt
        if self._modal is not None:
            _, cm, omega = self._modal
            return self._modal_solve(rhs, 1.0 + h * cm + h * h * omega**2)
        if self._average is None:
            a = sp.diags(self.m) + h * h * self.k
            if self._c is not None:
                a = a + h * self._c
            self._average = self._solver(a, None)
        return self._average(rhs)

    def _solver(self, a, diagonal):
        """
        Return the solve of ``a + (dt / 2) U D U^T`` (``a`` sparse, or ``diagonal`` given).

        The rank-``k`` part by Woodbury: ``A^-1 r - W (I + h D U^T W)^-1 h D U^T A^-1 r`` with
        ``W = A^-1 U``, made once.
        """
        if diagonal is not None:
            def base(r):
                return r / (diagonal if r.ndim == 1 else diagonal[:, None])
        else:
            base = factor_definite(a.tocsc(), points=self.points).solve
        if self._low is None:
            return base
        u, d = self._low
        w = base(u)
        hd = 0.5 * self.dt * d
        correction = np.linalg.solve(np.eye(d.size) + hd[:, None] * (u.T @ w), np.diag(hd))

        def solve(r):
            x = base(r)
            return x - w @ (correction @ (u.T @ x))
        return solve


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

    @property
    def damping_entries(self) -> DampingEntries:
        """Return what an explicit step multiplies for its damping (the work model prices it)."""
        return self._ops.explicit_entries(turning=self._world is not None)

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

    def omega_max(self) -> float:
        if self.basis is None:
            raise ValueError('stability limit needs the modal basis')
        return self.basis.omega_max_estimate()

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
        self._u, self._v, self._a = u, v, self._loaded(f, u, self.time) / self.model.mass_dof

    def displacement(self) -> np.ndarray:
        if self._world is not None:
            return self._world.to_frame(self._u, self._v, self.time)[0]
        return self._u.copy()

    def positions(self) -> np.ndarray:
        if self._world is not None:     # stepped in the world: where the particles are
            return self.model.positions3(self._world.positions(self._u, self.time))
        return super().positions()

    def velocity(self) -> np.ndarray:
        if self._world is not None:
            return self._world.to_frame(self._u, self._v, self.time)[1]
        return self._v.copy()

    @property
    def _last_max_strain(self) -> float:
        return self._forces.last_max_strain

    def _force(self, u: np.ndarray) -> np.ndarray:
        t = self._ending
        force = (self._world.force(u, t) if self._world is not None else self._forces(u, t))
        return self._loaded(force, u, t)

    def _loaded(self, force: np.ndarray, u: np.ndarray, t: float) -> np.ndarray:
        """Add the loads' forces at ``u``, ``t`` to ``force`` (in place; returned)."""
        if self.loads:
            # world coordinates (a turning clamp stepped in the world): the loads' own forces
            loaded = self._applied(of_vector(u), t, in_world=self._world is not None)
            if loaded is not None:
                np.add.at(force, loaded[0], loaded[1])
        return force

    def _step_once(self) -> None:
        ops = self._ops if self._world is None else self._world.at(self._ending)
        self._u, self._v, self._a = self._advance(self._u, self._v, self._a, self._force, ops)
        self._commit()

"""
Reduced force evaluation: the nonlinear spring forces every N steps, a tangent in between.

The paper's method (fig. 5) evaluates every spring of the scene on every step, so a modal step
costs about as much as a full physical one on a large scene; the modal gain is only the longer
step. In the small-deformation regime the paper works in, the generalized spring force of the
kept modes changes slowly and almost linearly, so :class:`RefreshedForces` evaluates it exactly
(eq. 20, every spring) only every ``interval`` steps, at ``q_k``, and in between continues it
along the tangent stiffness ``K_s`` of the static equilibrium under gravity:

    Q(q, t) = Q_spring(q_k) - K_s (q - q_k) + loads(t)

The loads (gravity, base excitation) stay exact at every step. ``K_s`` (m x m) holds the
stiffening of the sagged shape (tension, rotated springs), so what is held between refreshes is
only its change with the motion, which keeps a lagged coupling from feeding energy into the
modes. A step between refreshes costs a few operations on the kept modes, not on the springs.

``interval = 1`` is the paper's method exactly (:meth:`RefreshedForces.build` then gives the
exact model).
At each refresh the continued force is compared with the exact one; the relative difference,
``refresh_error`` (and its largest value since the last restart), is the measured cost in
accuracy, reported by the node on ``/diagnostics``. It checks itself: a refresh whose error
passes ``tolerance`` (the run's ``modal.tolerance``) makes every later step evaluate the springs
exactly (``fell_back``, reported with a WARN), before the lagging force can feed a divergence
(on a flag driven at its resonance the error grows past 100 % before it blows up).

Divergence stays detected on the step it happens: between refreshes the largest spring strain
is bounded by its exact value at the last refresh plus the most any spring can have stretched
since (``strain_sensitivity * |q - q_k|``), and a step whose bound passes ``strain_limit`` is
evaluated exactly.
"""
from __future__ import annotations

import math

from modal_spring_ros.core.forces.base import ForceContext, ForceModel, ForceOptions, ForceReport
from modal_spring_ros.core.forces.exact import ExactForces
import numpy as np

#: iterations of the static solve (modified Newton with the rest stiffness)
STATIC_ITERATIONS = 200
STATIC_RTOL = 1e-10


def static_equilibrium(forces: ExactForces, omega2: np.ndarray
                       ) -> tuple[np.ndarray, bool]:
    """
    Modal coordinates of the equilibrium under gravity, and whether it was found.

    Modified Newton with the rest stiffness ``diag(omega^2)`` as the fixed tangent: in the
    small-deformation regime it contracts by about the strain per iteration. Returns
    ``(zeros, False)`` when it does not converge (large deformation, or no stiffness).
    """
    q = np.zeros(omega2.size)
    gravity = forces.gravity()
    if not np.any(gravity) or not np.all(omega2 > 0.0):
        return q, not np.any(gravity)
    for _ in range(STATIC_ITERATIONS):
        step = (forces.elastic_forces(q) + gravity) / omega2
        q += step
        if not np.all(np.isfinite(q)):
            break
        if np.linalg.norm(step) <= STATIC_RTOL * max(np.linalg.norm(q), 1e-300):
            return q, True
    return np.zeros(omega2.size), False


class RefreshedForces(ForceModel):
    """
    Generalized forces with the springs evaluated every ``interval`` steps of ``dt``.

    ``forces(q, t)``, as every force model. A call at a time ``interval`` steps or more after
    the last evaluation (or before it: a restart) evaluates the springs exactly.

    :ivar static_found: the static equilibrium was found (else ``K_s`` is the rest stiffness).
    :ivar refresh_error: relative difference between the continued and the exact spring force
        at the last refresh; ``max_refresh_error`` the largest since :meth:`restart`.
    :ivar last_max_strain: largest spring strain at the last call: exact when the springs were
        evaluated, else an upper bound (never below the true value).
    :ivar strain_limit: a step whose strain bound passes it evaluates the springs exactly.
    :ivar fell_back: a refresh measured an error beyond ``tolerance``: every step is exact
        from then on (kept over restarts: the scene and band are what made it fail).
    :ivar calls: calls so far; ``evaluations`` of them evaluated the springs (both kept over
        restarts: what the run has cost, for the work model).
    """

    name = 'refreshed'

    @classmethod
    def build(cls, context: ForceContext, options: ForceOptions) -> ForceModel:
        """Return forces refreshed every ``options.refresh`` steps (every step: the exact ones)."""
        if options.refresh == 1:
            return context.exact
        return cls(context.exact, context.omega2, options.refresh, context.dt,
                   context.strain_limit, options.tolerance)

    def __init__(self, exact: ExactForces, omega2: np.ndarray, interval: int, dt: float,
                 strain_limit: float = math.inf, tolerance: float = math.inf):
        if interval < 1:
            raise ValueError(f'force refresh interval ({interval}) must be at least 1 step')
        self.exact = exact
        self.interval = int(interval)
        self.strain_limit = strain_limit
        self.tolerance = float(tolerance)
        self.fell_back = False
        self.fell_back_error = 0.0
        self.calls = self.evaluations = 0
        self._due = (self.interval - 0.5) * dt
        self._strain_gain = exact.strain_sensitivity()
        q_static, self.static_found = static_equilibrium(exact, omega2)
        self.tangent = exact.tangent(q_static) if self.static_found else np.diag(omega2)
        # errors are relative to the spring force, at least that of holding up gravity
        self._scale = max(float(np.linalg.norm(exact.gravity())), 1e-300)
        self.restart()

    def restart(self) -> None:
        """Forget the last evaluation (the state was set from outside)."""
        self._t = -math.inf
        self._q = self._spring = None
        self.refresh_error = 0.0
        self.max_refresh_error = 0.0
        self.last_max_strain = self._strain_at_refresh = 0.0

    def __call__(self, q: np.ndarray, t: float) -> np.ndarray:
        """
        Generalized force at ``q``, ``t``; sets ``last_max_strain``.

        Exact on an evaluation, else an upper bound of the largest spring strain.
        """
        force = None
        self.calls += 1
        if not self.fell_back and not (t - self._t >= self._due or t < self._t):
            dq = q - self._q
            bound = self._strain_at_refresh + self._strain_gain * math.sqrt(float(dq @ dq))
            if bound <= self.strain_limit:
                force = self._continued(dq)
                self.last_max_strain = bound
        if force is None:
            self.evaluations += 1
            spring = self.exact.elastic_forces(q)
            if self._q is not None and t >= self._t and not self.fell_back:
                continued = self._continued(q - self._q)
                scale = max(float(np.linalg.norm(spring)), self._scale)
                self.refresh_error = float(np.linalg.norm(spring - continued)) / scale
                self.max_refresh_error = max(self.max_refresh_error, self.refresh_error)
                if not self.refresh_error <= self.tolerance:  # NaN too
                    self.fell_back = True
                    self.fell_back_error = self.refresh_error
            self._t, self._q, self._spring = t, q.copy(), spring
            self._strain_at_refresh = self.last_max_strain = self.exact.last_max_strain
            force = spring.copy()
        force += self.exact.loads(t)
        return force

    @property
    def evaluated_share(self) -> float:
        """
        Return the share of calls so far that evaluated the springs.

        ``1 / interval`` until the calls span a few intervals (a reset evaluates at once).
        """
        if self.calls < 4 * self.interval:
            return 1.0 / self.interval
        return self.evaluations / self.calls

    def report(self) -> ForceReport:
        if self.fell_back:
            text = (f'exact every step (refreshed every {self.interval} steps fell back: error '
                    f'{self.fell_back_error:.2%} beyond {self.tolerance:.2%})')
        else:
            text = f'exact every {self.interval} steps, tangent between'
        return ForceReport(self.name, text, 1 if self.fell_back else self.interval,
                           self.max_refresh_error,
                           self.fell_back)

    def loads(self, t: float) -> np.ndarray:
        return self.exact.loads(t)

    def gravity(self) -> np.ndarray:
        return self.exact.gravity()

    def _continued(self, dq: np.ndarray) -> np.ndarray:
        """Return the last exact spring force continued along the static tangent by ``dq``."""
        return self._spring - self.tangent @ dq

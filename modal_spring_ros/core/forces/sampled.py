"""
Generalized forces with the springs sampled (ECSW).

A step whose cost does not depend on the number of springs.
The spring force is the weighted sum over the sampled springs
(:mod:`~modal_spring_ros.core.forces.sampling`), still nonlinear (eq. 20 on each sampled spring);
the loads stay exact. At a low rate (``check_every`` calls, by default spaced by the cost of a
check, :func:`check_spacing`) the exact force is evaluated beside it: the relative difference is
``sample_error`` (its largest value ``max_sample_error``), and the largest spring strain of that
evaluation is what divergence detection sees until the next one (the sampled springs' strain
otherwise). The sample is trained within a share of the tolerance; if its error on states it
was not trained on, or at run time, passes ``tolerance``, the forces fall back to exact ones
for good (``fell_back``), and the simulation reports it.

Where the sample comes from (trained on the scene's own motion, or from a store) is
:mod:`~modal_spring_ros.core.forces.samples`.
"""
from __future__ import annotations

import math

from modal_spring_ros.core.forces.base import ForceContext, ForceModel, ForceOptions, ForceReport
from modal_spring_ros.core.forces.exact import ExactForces
from modal_spring_ros.core.forces.samples import cached_sample
from modal_spring_ros.core.forces.sampling import DEFAULT_TOLERANCE, SpringSample
from modal_spring_ros.core.forces.springs import pull_springs
import numpy as np

#: fewest calls between two checks of the sampled force against the exact one
MIN_CHECK_EVERY = 200
#: a check costs about as much as (springs / sampled springs) sampled evaluations: checks are
#: spaced this many times that apart, so that they add at most a fifth of the sampled springs'
#: own cost and a step stays as cheap on a large scene as on a small one
CHECK_SPACING = 5


def check_spacing(springs: int, sampled: int) -> int:
    """Return the calls between two checks: a check's cost spread thin (at least 200)."""
    return max(MIN_CHECK_EVERY, math.ceil(CHECK_SPACING * springs / max(sampled, 1)))


class SampledForces(ForceModel):
    """``Q(q, t)`` with the springs sampled; see the module text."""

    name = 'sampled'
    trained = True

    @classmethod
    def build(cls, context: ForceContext, options: ForceOptions) -> 'SampledForces':
        """Return the springs sampled within ``options.tolerance`` (stored, or trained)."""
        if not (0.0 < options.tolerance < 1.0):
            raise ValueError(f'sampled forces need a tolerance between 0 and 1, not '
                             f'{options.tolerance:g}')
        sample = cached_sample(context.exact, context.phi, context.omega2, context.damping,
                               context.dt, options.tolerance, context.progress, context.worker,
                               context.samples)
        return cls(context.exact, sample, options.tolerance)

    def __init__(self, exact: ExactForces, sample: SpringSample,
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
        self._law = exact.law.subset(springs)
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
        strain = pull_springs(delta, self._law)
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

    def report(self) -> ForceReport:
        return ForceReport(self.name, self._describe(), 1, self.max_sample_error, self.fell_back)

    def _describe(self) -> str:
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
        force = self.exact.add_bending(self.spring_forces(q), q)   # bending: linear, exact
        force += self.exact.loads(t)
        return force

    def loads(self, t: float) -> np.ndarray:
        return self.exact.loads(t)

    def gravity(self) -> np.ndarray:
        return self.exact.gravity()

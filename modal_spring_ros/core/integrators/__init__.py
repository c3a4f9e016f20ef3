"""
Time integrators for ``M a + C v = F(u, t)``.

A contract, a name-to-class registry, one integrator a module.

* ``explicit`` (:class:`ExplicitNewmark`, beta = 0): the paper's scheme.
* ``average`` (:class:`AverageAcceleration`, beta = 1/4): implicit, unconditionally stable.

``mode_step`` reads what a registered integrator's step does to a vibration mode.
"""
from __future__ import annotations

import math

from modal_spring_ros.core.integrators.average import AverageAcceleration
from modal_spring_ros.core.integrators.base import (Integrator, NonConvergence, Operators,
                                                    StepResult)
from modal_spring_ros.core.integrators.diagonal import DiagonalOperators
from modal_spring_ros.core.integrators.explicit import ExplicitNewmark

#: integrator name -> class
INTEGRATORS: dict[str, type[Integrator]] = {
    cls.name: cls for cls in (ExplicitNewmark, AverageAcceleration)}


def integrator(name: str) -> Integrator:
    """Return the integrator registered as ``name``. Raises ValueError naming the choices."""
    try:
        return INTEGRATORS[name]()
    except KeyError:
        raise ValueError(f"integrator '{name}' must be one of {', '.join(INTEGRATORS)}") from None


def stable_step(name: str, omega_max: float) -> float:
    """Return integrator ``name``'s largest stable step up to ``omega_max`` rad/s (inf: any)."""
    return INTEGRATORS[name].stable_step(omega_max)


def conditionally_stable(name: str) -> bool:
    """Tell whether the integrator ``name`` is stable only below a step limit."""
    return math.isfinite(stable_step(name, 1.0))


__all__ = ['INTEGRATORS', 'AverageAcceleration', 'DiagonalOperators', 'ExplicitNewmark',
           'Integrator', 'NonConvergence', 'Operators', 'StepResult', 'conditionally_stable',
           'integrator', 'stable_step']

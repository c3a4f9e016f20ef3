"""
The steps a run may take: at least ``MIN_DT_S``, and within its integrator's stability limit.

A step given is refused at or above the limit of the coordinates it steps (:func:`check_step`);
a step taken from the limit (:func:`step_from_limit`) is refused where the limit itself is
below ``MIN_DT_S``, naming the scene's masses and springs (the step was nobody's).
"""
from __future__ import annotations

import math

from modal_spring_ros.core.integrators import AverageAcceleration, stable_step

#: Smallest time step, s: below it ``t + dt`` stops advancing within a long run's time range.
MIN_DT_S = 1e-8


class UnstableStepError(ValueError):
    """The run's integrator would be unstable for the coordinates stepped at this ``dt``."""


def check_step(integrator: str, dt: float, omega_max: float, method: str, dt_name: str = 'dt'
               ) -> None:
    """Refuse a step at or above ``integrator``'s stability limit up to ``omega_max`` rad/s."""
    limit = stable_step(integrator, omega_max)
    if dt >= limit:
        raise UnstableStepError(
            f'{dt_name} ({dt:g} s) is at or above the {integrator} stability limit '
            f"{limit:.4g} s of the {method} run's highest mode "
            f'({omega_max / (2.0 * math.pi):.4g} Hz): lower {dt_name}, keep fewer high modes '
            f"(a lower upper band edge), or use the 'average' integrator")


def stable_step_limit(omega_max: float) -> float:
    """Return the explicit step's limit up to ``omega_max`` (what a run's stability limit is)."""
    return stable_step('explicit', omega_max)


def step_from_limit(limit: float, share: float, scene: str, fallback: float = 1e-3) -> float:
    """
    Return ``share`` of the explicit stability ``limit`` (``fallback`` where it has none).

    :raises ValueError: that is below ``MIN_DT_S``: the scene's masses are too light for its
        springs (particles of 1e-300 kg), named as such rather than as a step nobody gave.
    """
    step = share * limit if math.isfinite(limit) else fallback
    if step < MIN_DT_S:
        raise ValueError(
            f"scene '{scene}': its explicit stability limit ({limit:.3g} s) is below the "
            f'shortest step a run takes ({MIN_DT_S:g} s): its masses are too light for its '
            f"springs' stiffness (the highest mode at {1.0 / (math.pi * max(limit, 1e-300)):.3g} "
            f'Hz); use heavier particles, softer springs, or the integrator '
            f"'{AverageAcceleration.name}'")
    return step

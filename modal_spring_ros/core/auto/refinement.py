"""
What a plan can become: its refinements one at a time, and its richer sibling.

The pilot (:mod:`~modal_spring_ros.core.auto.pilot`) refines a plan that measures beyond its
share of the tolerance by trying each refinement it still has alone (:func:`refinements`), and
measures it against the full run or, where that is beyond its budget, against a richer sibling
(:func:`richer`): an embedded pair, every respect of the plan one rung up. A sibling shares a
share of the plan's step error (:func:`shared_step_error`), and is kept for a refined plan only
while it is still richer in every respect (:func:`still_richer`). A plan well within its share
has its step lengthened (:func:`lengthened`).
"""
from __future__ import annotations

import dataclasses
from typing import Callable, Iterator

from modal_spring_ros.core.auto.full_candidate import STEP_ORDER
from modal_spring_ros.core.auto.plan import PlanSettings
from modal_spring_ros.core.bases.mode_selection import choose_refresh
from modal_spring_ros.core.simulations import Simulation

#: Most derivative directions a refinement asks for.
MAX_PILOT_DIRECTIONS = 96
#: The richer sibling's step is made this many times shorter than the plan's, and kept for a
#: refined plan while it is at least ``SIBLING_KEPT`` times shorter.
SIBLING_REFINEMENT, SIBLING_KEPT = 4.0, 2.0

#: Longest step a plan is lengthened to, as a share of its explicit stability limit (below
#: ``mode_selection.STABILITY_SAFETY``, beyond which a plan's step is cut to a safe one).
LONGEST_STEP = 0.85

#: ``more_modes(hz)``: the next mode limit above ``hz`` the band allows (None: none).
MoreModes = Callable[[float], 'float | None']


def refinements(plan: PlanSettings, more_modes: MoreModes, can_halve_step: bool,
                shortest_dt: float = 0.0) -> Iterator[tuple[str, PlanSettings]]:
    """
    Yield each refinement ``plan`` still has, by name: forces, basis, directions, modes, step.

    The step is halved only where it is the plan's to choose, and never below ``shortest_dt``
    (the step the full run itself needed to converge: a finer plan step buys nothing).
    """
    if plan.forces != 'exact':
        yield 'exact forces', dataclasses.replace(plan, forces='exact', refresh=1)
    if plan.basis_kind == 'rest':
        yield 'derivatives basis', dataclasses.replace(plan, basis_kind='derivatives')
    elif plan.directions < MAX_PILOT_DIRECTIONS:
        yield 'more directions', dataclasses.replace(
            plan, directions=min(MAX_PILOT_DIRECTIONS, 2 * plan.directions))
    more = more_modes(plan.highest_hz)
    if more is not None:
        yield 'more modes', dataclasses.replace(plan, highest_hz=more)
    if can_halve_step and plan.dt / 2 >= shortest_dt:
        yield 'half the step', dataclasses.replace(
            plan, dt=plan.dt / 2, refresh=plan.refresh * 2 if plan.forces == 'refreshed' else 1)


def richer(plan: PlanSettings, dt: float, more_modes: MoreModes) -> PlanSettings:
    """
    Return the plan's richer sibling: finer forces, more directions and modes, a quarter step.

    ``dt``: the step the plan was built with (a step cut to its stability limit when built).
    Its forces are one rung above the plan's: a sampled plan's sibling evaluates every spring
    on the refresh that tracks the exact forces (half a period of its highest mode: within
    0.03 % of every step, a tenth of the cost on a 10,000-particle sheet); a refreshed or exact
    plan's evaluates every spring on every step.
    """
    highest = more_modes(plan.highest_hz) or plan.highest_hz
    step = min(plan.dt, dt) / SIBLING_REFINEMENT
    refreshed = plan.forces == 'sampled'
    return dataclasses.replace(
        plan, forces='refreshed' if refreshed else 'exact',
        refresh=choose_refresh(highest, step) if refreshed else 1, basis_kind='derivatives',
        directions=min(MAX_PILOT_DIRECTIONS, 2 * plan.directions), highest_hz=highest, dt=step)


def shared_step_error(sibling_dt: float, dt: float) -> float:
    """
    Return the Richardson factor of a plan at ``dt`` measured against a sibling at ``sibling_dt``.

    The sibling shares ``(sibling_dt / dt)^2`` of the plan's step error (second order), so the
    difference is divided by the rest; 1 where the sibling is not at least ``SIBLING_KEPT``
    times finer.
    """
    ratio = sibling_dt / dt
    finer = ratio <= (1.0 + 1e-6) / SIBLING_KEPT
    return 1.0 / (1.0 - ratio ** STEP_ORDER) if finer else 1.0


def still_richer(sibling: PlanSettings, sibling_dt: float, plan: PlanSettings, dt: float,
                 more_modes: MoreModes) -> bool:
    """Tell whether ``sibling`` is still richer than the refined ``plan`` in every respect."""
    return (dt * (1.0 + 1e-6) >= SIBLING_KEPT * sibling_dt
            and (sibling.forces == 'exact' or plan.forces == 'sampled')
            and (plan.highest_hz < sibling.highest_hz or more_modes(plan.highest_hz) is None)
            and (plan.basis_kind == 'rest' or plan.directions < sibling.directions
                 or plan.directions >= MAX_PILOT_DIRECTIONS))


def lengthened(plan: PlanSettings, sim: Simulation, error: float, budget: float,
               build: Callable[[PlanSettings], Simulation],
               measured: Callable[[Simulation], 'float | None']
               ) -> tuple[PlanSettings, Simulation, float, bool]:
    """
    Return the plan at the longest step (up to ``LONGEST_STEP`` of its limit) within ``budget``.

    A plan well within its budget pays for accuracy nobody asked for. Its step is lengthened
    (at most doubled) to where its step error (second order) would reach 90 % of the budget,
    and kept where the error ``measured(trial)`` gives is within it (None: not measured, as the
    planning budget is spent); twice at most. Whether any longer step was kept is last.
    """
    longer = False
    for _ in range(2):
        reach = (0.9 * budget / error) ** (1.0 / STEP_ORDER) if error > 0.0 else 2.0
        step = min(min(2.0, reach) * sim.dt, LONGEST_STEP * sim.stability_limit())
        if step <= sim.dt * 1.1:
            break
        candidate = dataclasses.replace(plan, dt=step)
        trial = build(candidate)
        if trial.dt <= sim.dt * 1.05:
            break
        error_then = measured(trial)
        if error_then is None or error_then > budget:
            break
        plan, sim, error, longer = candidate, trial, error_then, True
    return plan, sim, error, longer

"""
What a run costs, modelled: microseconds of one core per simulated second.

The automatic choice compares plans (and the full run) by this model, not by a clock, so that
the same scene and settings give the same plan on any machine, under any load, with any number
of BLAS threads. Its constants are fitted to per-step CPU times of full and modal runs
(``modal_spring_bench --suite promise`` measures them against it).
"""
from __future__ import annotations

from modal_spring_ros.core.simulations import Simulation

#: The work model, in microseconds of one core (fitted to per-step CPU times of full and modal
#: runs from 2 to 40,000 springs, single-threaded BLAS; the fixed costs refitted on 113 runs of
#: 9 to 1,000 particles, where they dominate): a step's fixed cost (full, modal), per spring
#: evaluated, per free DOF of a full step, per free DOF and stepped coordinate (the two products
#: with the shapes), per pair of coordinates (the modal step's dense products) and per pair of a
#: refreshed step's tangent.
STEP_US = {'full': 45.0, 'modal': 25.0}
SPRING_US, DOF_US, PROJECTION_US, PAIR_US, TANGENT_US = 0.02, 0.02, 0.0005, 0.0003, 0.0005
#: A turning clamp's step also computes the frame's motion and its inertial loads (full, modal).
TURNING_STEP_US = {'full': 80.0, 'modal': 60.0}


def work_per_second(sim: Simulation) -> float:
    """
    Return the modelled CPU time ``sim`` takes per simulated second, us (see ``STEP_US``).

    Deterministic (no clock is read), so that the same scene and settings give the same plan on
    any machine and under any load. A sampled plan is taken to evaluate about four springs per
    coordinate (its sample is trained only once the plan is chosen).
    """
    model = sim.model
    springs = model.scene.n_springs
    kind = 'full' if sim.method == 'full' else 'modal'
    fixed = STEP_US[kind] + (TURNING_STEP_US[kind] if model.rotates else 0.0)
    if kind == 'full':
        return (fixed + SPRING_US * springs + DOF_US * model.n_free_dof) / sim.dt
    coords = sim.coordinates
    fixed += PAIR_US * coords * coords
    if getattr(sim, 'sample_tolerance', None) is not None:
        evaluated = float(min(springs, 4 * coords))
        per_step = (fixed + SPRING_US * evaluated
                    + PROJECTION_US * evaluated * 2 * model.dimension * coords)
    else:
        evaluation = SPRING_US * springs + PROJECTION_US * model.n_free_dof * coords
        tangent = TANGENT_US * coords * coords if sim.force_refresh > 1 else 0.0
        per_step = fixed + evaluation / sim.force_refresh + tangent
    return per_step / sim.dt

"""
What a run costs, modelled: microseconds of one core per simulated second.

The automatic choice compares plans by this model, not by a clock, so that the same scene and
settings give the same plan on any machine, under any load, with any number of BLAS threads.
Its constants are fitted to per-step CPU times of full and modal runs
(``modal_spring_bench --suite promise`` measures them against it). It tells a modal plan's
cost from the full run's to about 30 % (5th to 95th percentile of the modal-to-full ratio over
the fit's runs: 0.70-1.65 times the measured ratio, median 0.99). A clock is never read: timing
the two on the machine at hand was tried for near ties, and on a loaded machine it turned a
plan modelled at 0.64x the full run into the full run.
"""
from __future__ import annotations

from modal_spring_ros.core.simulations import Simulation

#: The work model, in microseconds of one core, fitted (non-negative least squares on relative
#: error) to the per-step CPU times of 664 runs, single-threaded BLAS: the full run and modal
#: runs of 4 to 273 coordinates (rest and derivative bases, exact and refreshed forces) on 38
#: random scenes of 9 to 80 particles and sheet_10x10 and sheet_32x32. A step's fixed cost and
#: the extra of a turning clamp (the frame's motion and its inertial loads), per spring
#: evaluated (full, modal: a modal evaluation also gathers and scatters through the shapes);
#: for a modal step, per coordinate, per pair of coordinates with a turning clamp (the
#: Coriolis coupling), per spring evaluation (its fixed cost) and per free DOF and coordinate
#: on an evaluation (the two products with the shapes).
STEP_US = {'full': 25.3, 'modal': 11.1}
TURNING_STEP_US = {'full': 56.0, 'modal': 38.0}
SPRING_US = {'full': 0.025, 'modal': 0.037}
DOF_US = 0.0
COORDINATE_US, TURNING_PAIR_US, EVALUATION_US, PROJECTION_US = 0.106, 0.0046, 3.8, 0.00009


def work_per_second(sim: Simulation) -> float:
    """
    Return the modelled CPU time ``sim`` takes per simulated second, us (see ``STEP_US``).

    Deterministic (no clock is read), so that the same scene and settings give the same plan on
    any machine and under any load. Refreshed forces count the share of steps that evaluated
    the springs so far (a strain bound or a restart evaluates more often than every
    ``force_refresh`` steps; the pilot has stepped every plan it compares), ``1 / force_refresh``
    before the first step. A sampled plan is taken to evaluate about four springs per
    coordinate (its sample is trained only once the plan is chosen).
    """
    model = sim.model
    springs = model.scene.n_springs
    kind = 'full' if sim.method == 'full' else 'modal'
    fixed = STEP_US[kind] + (TURNING_STEP_US[kind] if model.rotates else 0.0)
    if kind == 'full':
        return (fixed + SPRING_US['full'] * springs + DOF_US * model.n_free_dof) / sim.dt
    coords = sim.coordinates
    fixed += COORDINATE_US * coords + (TURNING_PAIR_US * coords * coords if model.rotates
                                       else 0.0)
    if sim.forces.model == 'sampled':
        evaluated = float(min(springs, 4 * coords))
        per_step = (fixed + EVALUATION_US + SPRING_US['modal'] * evaluated
                    + PROJECTION_US * evaluated * 2 * model.dimension * coords)
    else:
        evaluation = (EVALUATION_US + SPRING_US['modal'] * springs
                      + PROJECTION_US * model.n_free_dof * coords)
        per_step = fixed + sim.evaluated_share * evaluation
    return per_step / sim.dt

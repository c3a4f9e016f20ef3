"""
What a run costs, modelled: microseconds of one core per simulated second.

The automatic choice compares plans by this model, not by a clock, so that the same scene and
settings give the same plan on any machine, under any load, with any number of BLAS threads.
Its constants are fitted to per-step CPU times of full and modal runs
(``modal_spring_bench --suite promise`` measures them against it); it tells costs apart to
about 30 % (5th to 95th percentile of the modal-to-full ratio over the fit's runs: 0.70-1.65
times the measured). Where the plan and the full run come within that of each other (a near
tie, :func:`cost_ratio`), both are timed on this machine instead, in CPU seconds of this
process (all its threads), best of a few interleaved rounds: the choice between them then
follows what each costs here, and may differ between machines where they cost about the same.
"""
from __future__ import annotations

import time

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
    if getattr(sim, 'sample_tolerance', None) is not None:
        evaluated = float(min(springs, 4 * coords))
        per_step = (fixed + EVALUATION_US + SPRING_US['modal'] * evaluated
                    + PROJECTION_US * evaluated * 2 * model.dimension * coords)
    else:
        evaluation = (EVALUATION_US + SPRING_US['modal'] * springs
                      + PROJECTION_US * model.n_free_dof * coords)
        per_step = fixed + sim.evaluated_share * evaluation
    return per_step / sim.dt


#: Modelled costs within this factor of each other are a near tie: both runs are timed.
NEAR_TIE = 1.4
#: Each run is timed over this much simulated time (within the step counts), best of rounds.
TIMED_S, TIMED_STEPS, TIMED_ROUNDS = 0.2, (20, 2000), 3


def cost_ratio(sim: Simulation, other: Simulation) -> tuple[float, bool]:
    """
    Return ``sim``'s cost per simulated second over ``other``'s, and whether it was timed.

    The work model's ratio, unless it is a near tie (within ``NEAR_TIE``): then each run's CPU
    time per simulated second, best of ``TIMED_ROUNDS`` interleaved rounds. Both runs are reset
    to rest afterwards.
    """
    modelled = work_per_second(sim) / work_per_second(other)
    if not 1.0 / NEAR_TIE < modelled < NEAR_TIE:
        return modelled, False
    best = [float('inf'), float('inf')]
    for _ in range(TIMED_ROUNDS):
        for k, run in enumerate((sim, other)):
            best[k] = min(best[k], _cpu_per_second(run))
    return best[0] / best[1], True


def _cpu_per_second(sim: Simulation) -> float:
    """Return the CPU seconds (this process) ``sim`` takes per simulated second, from rest."""
    low, high = TIMED_STEPS
    steps = min(high, max(low, int(round(TIMED_S / sim.dt))))
    sim.reset()
    start = time.process_time()
    sim.step(steps)
    spent = time.process_time() - start
    sim.reset()
    return max(spent, 1e-9) / (steps * sim.dt)

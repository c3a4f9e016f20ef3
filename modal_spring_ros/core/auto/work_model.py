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
#: A full step's damping beyond a diagonal one, per entry it multiplies (its
#: :class:`~modal_spring_ros.core.simulations.full.DampingEntries`), fitted to explicit full runs
#: of sheets and blocks of 180 to 9,660 free DOF (single-threaded BLAS), each against the same
#: scene with mass-proportional damping: a modal ratio over every mode (its n x n matrix:
#: 0.00033-0.00036 us an entry), over the lowest modes (0.00019-0.00028 us an entry of their
#: four products), and a ``beta K`` term (its product and its factor's solve: 0.0046-0.0061 us
#: per stored entry of ``K``). Unpriced, these made such a full run cost 1.1-5.2 times its model.
DENSE_US, LOW_RANK_US, STIFFNESS_US = 0.00034, 0.00026, 0.0057
#: A step's contact with the scene's colliders (:mod:`~modal_spring_ros.core.loads.contact`),
#: fitted to explicit runs of a volume of 162 and 671 free particles on a floor with 0 to 4
#: colliders (single-threaded BLAS): a fixed cost and its share per free particle, then per
#: collider and per collider and free particle (each measures every particle's distance); a
#: modal step also takes the particles' positions from its coordinates and projects the touches'
#: forces on its shapes. Unpriced, contact made a full run of a box on a floor cost 4.5 times
#: its model (the step's fixed cost of 25 us against the contact's 130-190 us).
CONTACT_US, CONTACT_PARTICLE_US, COLLIDER_US, COLLIDER_PARTICLE_US = 90.0, 0.035, 32.0, 0.083
MODAL_CONTACT_US = 60.0


def work_per_second(sim: Simulation) -> float:
    """
    Return the modelled CPU time ``sim`` takes per simulated second, us (see ``STEP_US``).

    Deterministic (no clock is read), so that the same scene and settings give the same plan on
    any machine and under any load. Refreshed forces count the share of steps that evaluated
    the springs so far (a strain bound or a restart evaluates more often than every
    ``force_refresh`` steps; the pilot has stepped every plan it compares), ``1 / force_refresh``
    before the first step. A sampled plan is taken to evaluate about four springs per
    coordinate (its sample is trained only once the plan is chosen). An implicit step pays for
    each force evaluation of its iteration (:attr:`Simulation.evaluations_per_step`: counted
    once stepped, as the pilot has; the integrator's guess before). A full run's damping is
    priced as its explicit step multiplies it (``DENSE_US``; auto's full runs are explicit), and
    a step's contact with the scene's colliders (:func:`contact_work`).
    """
    model = sim.model
    springs = model.scene.n_springs
    kind = 'full' if sim.method == 'full' else 'modal'
    fixed = (STEP_US[kind] + (TURNING_STEP_US[kind] if model.rotates else 0.0)
             + contact_work(model, kind))
    evaluations = sim.evaluations_per_step
    if kind == 'full':
        damping = sim.damping_entries
        return (fixed + SPRING_US['full'] * springs * evaluations + DOF_US * model.n_free_dof
                + DENSE_US * damping.dense + LOW_RANK_US * damping.low_rank
                + STIFFNESS_US * damping.stiffness) / sim.dt
    coords = sim.coordinates
    fixed += COORDINATE_US * coords + (TURNING_PAIR_US * coords * coords if model.rotates
                                       else 0.0)
    if sim.forces.model == 'sampled':
        evaluated = float(min(springs, 4 * coords))
        per_step = fixed + evaluations * (
            EVALUATION_US + SPRING_US['modal'] * evaluated
            + PROJECTION_US * evaluated * 2 * model.dimension * coords)
    else:
        evaluation = (EVALUATION_US + SPRING_US['modal'] * springs
                      + PROJECTION_US * model.n_free_dof * coords)
        per_step = fixed + evaluations * sim.evaluated_share * evaluation
    return per_step / sim.dt


def contact_work(model, kind: str) -> float:
    """Return what a step's contact with the scene's colliders costs, us (``CONTACT_US``)."""
    contact = model.scene.contact
    if contact is None:
        return 0.0
    free = model.free_particles.size
    colliders = len(contact.colliders)
    return (CONTACT_US + CONTACT_PARTICLE_US * free
            + colliders * (COLLIDER_US + COLLIDER_PARTICLE_US * free)
            + (MODAL_CONTACT_US if kind == 'modal' else 0.0))

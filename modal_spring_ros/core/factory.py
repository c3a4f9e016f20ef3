"""
Build a ready-to-step simulation from a scene and a :class:`SimulationConfig`.

The command-line tools, the ROS node, the re-simulation of bags and the benchmark all go
through :func:`build_simulation`, so a run described by the same configuration is the same run
everywhere (bit for bit: the engine is deterministic).
"""
from __future__ import annotations

import dataclasses
import math

from modal_spring_ros.core.auto.budget import modes_work, PlanningBudget, setup_work
from modal_spring_ros.core.auto.measured_error import on_samples
from modal_spring_ros.core.auto.pilot import Pilot, PILOT_MARGIN, SAMPLES as PILOT_SAMPLES
from modal_spring_ros.core.auto.pilot_window import pilot_window
from modal_spring_ros.core.auto.plan import PlanSettings
from modal_spring_ros.core.auto.step_error import (predicted_step, predicting_hz, predicts,
                                                   StepPrediction)
from modal_spring_ros.core.auto.unplanned_full import unplanned_full
from modal_spring_ros.core.auto.watch.twin_watch import twin_reference
from modal_spring_ros.core.bases.basis import INITIAL_MODES, ModalBasis, Progress
from modal_spring_ros.core.bases.basis_choice import choose_basis
from modal_spring_ros.core.bases.mode_selection import (choose_modes, choose_refresh, choose_step,
                                                        ModeChoice, SHARE, STABILITY_SAFETY)
from modal_spring_ros.core.config import (AUTO_DT_SAFETY, DEFAULT_REFRESH, POSE_SOURCES,
                                          SAMPLE_MIN_SPRINGS, SimulationConfig)
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.forces import ForceOptions
from modal_spring_ros.core.forces.base import SampleStore
from modal_spring_ros.core.integrators import conditionally_stable
from modal_spring_ros.core.loads.pull import REACH_MIN_M
from modal_spring_ros.core.memory_estimate import check_run_memory
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.model.scene import Scene
from modal_spring_ros.core.motion.clamp_follower import ClampFollower
from modal_spring_ros.core.simulations import (DEFAULT_MAX_MODES, FullSimulation, ModalSettings,
                                               ModalSimulation, Simulation, step_from_limit)
from modal_spring_ros.core.simulations.coordinates import AddedCoordinateBank, shared_bank
from modal_spring_ros.core.simulations.early_step_check import check_step_before_modes, mode_cap
from modal_spring_ros.core.worker import WorkerProcess
import numpy as np


def rebuild(model: MassSpringModel, basis: ModalBasis, config: SimulationConfig,
            dt_name: str = 'dt') -> Simulation:
    """
    Return a new simulation (at rest) of the same scene and basis with other settings.

    A modal run with a given explicit step is refused (:class:`UnstableStepError`, naming the
    step ``dt_name``) before the modes its band needs are computed past the stability limit.

    With ``config.auto`` (modal), the fewest modes meeting ``config.tolerance`` are kept and,
    unless ``config.dt`` is given, the step follows from them, and unless
    ``config.force_refresh`` is given, so does the spring-force refresh; the basis (rest modes
    or their derivatives) is chosen by its predicted error and cost
    (:mod:`~modal_spring_ros.core.bases.basis_choice`) in place of ``config.basis``, and so are the
    forces in place of ``config.forces``: sampled springs on large scenes, refreshed ones in
    small deformation, every spring on every step beyond it. The choice is the
    simulation's ``mode_choice``.
    """
    config.validate()
    dt = config.dt or model.scene.default_dt
    if config.method == 'modal' and config.auto:
        return _automatic(model, basis, config)
    if config.method == 'modal':
        forces = config.forces
        refresh = config.force_refresh or (DEFAULT_REFRESH if forces == 'refreshed' else 1)
        bank = shared_bank(basis, config.derivative_directions)
        plan = PlanSettings(math.inf, config.basis, config.derivative_directions, forces,
                            refresh, dt or 0.0)
        if config.dt is not None:
            check_step_before_modes(basis, config.band, dt=config.dt,
                                    integrator=config.integrator, highest_hz=None,
                                    max_modes=mode_cap(basis, config.max_modes), dt_name=dt_name)
        return _modal(model, basis, config, bank, None, plan, keep_dt=config.dt is not None)
    sim = FullSimulation(model, basis, config.band, dt=dt or 1e-3,
                         integrator=config.integrator, strain_limit=config.strain_limit)
    # the scene's step is a modal run's: beyond the full run's stability it gives way, as a
    # plan's suggested step does (a step given is kept, and checked by the caller)
    beyond = bool(dt) and config.dt is None and conditionally_stable(config.integrator) and (
        dt >= STABILITY_SAFETY * sim.stability_limit())
    return sim if dt and not beyond else _within_stability(sim)


def _within_stability(sim: Simulation) -> Simulation:
    """``sim`` at ``AUTO_DT_SAFETY`` of its stability limit (no step was given)."""
    return sim.with_dt(step_from_limit(sim.stability_limit(), AUTO_DT_SAFETY,
                                       sim.model.scene.name))


def _modal(model: MassSpringModel, basis: ModalBasis, config: SimulationConfig,
           bank: AddedCoordinateBank, choice: ModeChoice | None, plan: PlanSettings,
           keep_dt: bool) -> Simulation:
    """
    Return the modal run of ``plan``.

    (``highest_hz`` inf: the whole band; ``dt`` 0: from the stability limit.)

    An explicit step the plan suggests beyond the stability limit of what it steps (the added
    coordinates included) gives way to ``AUTO_DT_SAFETY`` of that limit, unless it was given.
    """
    from_limit = not keep_dt and not plan.dt   # the step from what the band steps
    settings = ModalSettings(
        dt=plan.dt or 1e-3, integrator=config.integrator, transition_s=config.transition_s,
        max_modes=config.max_modes, strain_limit=config.strain_limit,
        highest_hz=plan.highest_hz if math.isfinite(plan.highest_hz) else None,
        forces=force_options(plan.forces, plan.refresh, config.tolerance),
        basis_kind=plan.basis_kind, derivative_directions=plan.directions,
        step_share=AUTO_DT_SAFETY if from_limit else None)
    sim: Simulation = ModalSimulation(model, basis, config.band, settings, mode_choice=choice,
                                      bank=bank, progress=basis.progress)
    if keep_dt or from_limit:
        return sim
    if conditionally_stable(config.integrator) and plan.dt >= STABILITY_SAFETY * (
            sim.stability_limit()):
        return _within_stability(sim)
    return sim


def force_options(forces: str, refresh: int, tolerance: float) -> ForceOptions:
    """
    Return the force model a run's ``forces`` setting and refresh give.

    ``exact`` with a refresh above 1 step is refreshed (``modal.force_refresh`` alone asks for
    it; refreshed every step is exact); the tolerance is what a model falls back beyond.
    """
    if forces == 'exact' and refresh > 1:
        forces = 'refreshed'
    return ForceOptions(forces, refresh, tolerance)


def _automatic(model: MassSpringModel, basis: ModalBasis, config: SimulationConfig,
               measured: bool = True) -> Simulation:
    """
    ``modal.auto``: the plan the prediction gives, then measured by a pilot run and refined.

    (:mod:`~modal_spring_ros.core.auto.pilot`); the full run where it is cheaper or the plan cannot
    be brought within the tolerance (bands that keep every mode only). Not ``measured``: the
    plan as predicted, with no pilot.
    """
    everything = config.band.kind == 'allpass'

    def full(longest_dt: float, sample_s: float) -> Simulation:
        # explicit, within its stability limit and no longer than ``longest_dt`` (the pilot
        # chooses: the longest that measures within the tolerance, a converged one for a
        # reference), landing on the pilot's samples
        sim = FullSimulation(model, basis, config.band, dt=1e-3, integrator='explicit',
                             strain_limit=config.strain_limit)
        step = min(STABILITY_SAFETY * sim.stability_limit(), longest_dt)
        return on_samples(sim, sample_s, step)

    horizon_s = config.horizon_s or model.scene.default_duration
    longest = full(math.inf, horizon_s)
    # the step ``method full`` takes (the given one, the scene's, or half the stability limit),
    # within stability
    full_dt = min(config.dt or model.scene.default_dt
                  or AUTO_DT_SAFETY * longest.stability_limit(), longest.dt)
    # a run of known length: what planning may spend is a share of its full run
    budget = (PlanningBudget.for_run(longest, config.horizon_s, config.planning_share)
              if everything else PlanningBudget())
    limit = min(config.max_modes or DEFAULT_MAX_MODES, basis.n_dof)
    sampled = model.scene.n_springs >= SAMPLE_MIN_SPRINGS
    why = _not_worth_planning(model, budget, basis, sampled)
    charged = [basis.modes_solved]

    def charge_modes() -> None:   # modes solved for since last counted, against the budget
        if not basis.dense:
            budget.spend(modes_work(model, basis.modes_solved - charged[0]))
            charged[0] = basis.modes_solved

    def affords_modes(solved: int) -> bool:   # each solve judged by what is left after the last
        charge_modes()
        return budget.affords(modes_work(model, solved))
    # every mode of a small scene, the lowest of a large one driven slowly enough for them
    # (more of them where its drive is faster, as the budget affords): the longest stable step
    # the full run is predicted to meet the tolerance at over the run, within the pilot's
    # margin (a scene with colliders is checked over the whole window instead: a linear
    # prediction sees no touch) (a step the user gave is the longest); only a budgeted run
    # takes the full run unmeasured or solves more modes for it (an unbudgeted one uses the
    # modes it has: its full candidate stops at the step they predict, where its window agrees)
    predicting = measured and everything and model.scene.contact is None

    def predict() -> StepPrediction | None:
        if predicting and budget.bounded and not predicts(model, basis):
            basis.ensure_frequency(predicting_hz(model), limit, affords_modes)
            charge_modes()
        return (predicted_step(model, basis, 'explicit', full_dt, horizon_s,
                               PILOT_MARGIN * config.tolerance, None if config.dt else longest.dt)
                if predicting and predicts(model, basis) else None)
    predicted = predict()
    choice = None
    if not why:
        # a large scene's band solves for its modes as the budget affords (each solve charged)
        choice = choose_modes(model, basis, config.band, config.tolerance, max_modes=limit,
                              affords=affords_modes if measured and not basis.dense else None)
        if choice is None:
            why = (f'the modes its band needs (beyond the {basis.count} solved for) would '
                   f'cost more than {budget.describe_left()}')
            # no plan is made: the set-up counted for it beyond its modes (their derivatives,
            # a sample) is not spent, and may pay for the modes that predict the full run's step
            budget.release(setup_work(model, sampled, 0))
            predicted = predicted or predict()
    if measured and why:
        # a plan's set-up would cost more than it could save: the full run, before any plan
        window = min(pilot_window(model, basis.frequencies_hz[:1]), horizon_s)
        sim, report = unplanned_full(full, budget, full_dt, window, horizon_s, config.tolerance,
                                     PILOT_MARGIN, PILOT_SAMPLES, why, predicted)
        sim.pilot = dataclasses.replace(report, planning=budget.describe())
        sim.watch_reference = twin_reference(sim, config.tolerance)
        return sim
    if choice is None:
        choice = choose_modes(model, basis, config.band, config.tolerance, max_modes=limit)
    charge_modes()
    bank = shared_bank(basis, config.derivative_directions)
    chosen = choose_basis(model, basis, choice.modes, SHARE * config.tolerance,
                          lambda keep: bank.for_band(keep)[1])
    choice = dataclasses.replace(choice, basis=chosen)
    dt = config.dt or choose_step(choice, config.integrator, config.tolerance,
                                  model.scene.damping)
    forces = 'sampled' if sampled else 'refreshed' if chosen.small else 'exact'
    refresh = config.force_refresh or (
        choose_refresh(choice.highest_hz, dt) if forces == 'refreshed' else 1)
    plan = PlanSettings(choice.highest_hz, chosen.kind, config.derivative_directions, forces,
                        refresh, dt)
    keep_dt = config.dt is not None

    def make(settings: PlanSettings) -> Simulation:
        return _modal(model, basis, config, bank, choice, settings, keep_dt)
    if not measured:
        return make(plan)

    planning = True

    def made(settings: PlanSettings) -> Simulation:   # each plan the pilot measures, said
        if planning:                                   # (not the watch's runs after it)
            basis.progress(f'planning: measuring {settings.describe()}')
        return make(settings)

    def more_modes(hz: float) -> float | None:
        found = _more_modes(basis, config.band, hz, limit, budget if planning else None)
        charge_modes()
        return found

    pilot = Pilot(model, config.tolerance, made, full if everything else None, more_modes,
                  basis.frequencies_hz[choice.modes], can_halve_step=not keep_dt,
                  horizon_s=horizon_s, budget=budget, full_dt=(full_dt, predicted))
    sim, report = pilot.run(plan)
    planning = False
    sim.pilot = report
    sim.watch_reference = (pilot.watch_reference(sim) if report.method == 'modal'
                           else twin_reference(sim, config.tolerance))
    return sim


def _not_worth_planning(model: MassSpringModel, budget: PlanningBudget, basis: ModalBasis,
                        sampled: bool) -> str:
    """
    Return why a plan is not worth making for a run of ``budget``'s length ('' where it is).

    The whole full run costs less than making a plan (``SMALL_RUN_US``), or a scene beyond the
    dense limit would spend more than the budget on its plan's set-up (its modes, their
    derivatives, a spring sample: :func:`~modal_spring_ros.core.auto.budget.setup_work`), which
    is otherwise counted against the budget.
    """
    if budget.small:
        return (f'the whole full run costs {budget.full_us / 1e6:.3g} s of CPU (modelled): '
                'less than choosing and building a plan')
    if basis.dense or not budget.bounded:
        return ''
    setup = setup_work(model, sampled, basis.modes_solved)
    if not budget.affords(setup):
        parts = 'its modes, their derivatives' + (', a spring sample' if sampled else '')
        return (f'making a plan ({parts}: about {setup / 1e6:.3g} s of CPU, modelled) would '
                f'cost more than {budget.describe_left()}')
    budget.spend(setup)
    return ''


def _more_modes(basis: ModalBasis, band: FilterBand, hz: float, limit: int,
                budget: PlanningBudget | None = None) -> float | None:
    """
    Return a mode limit with half as many more modes of ``band`` as up to ``hz`` (or None).

    None also where solving for them would pass ``budget`` (what solving costs is counted by
    the caller from ``basis.modes_solved``).
    """
    def kept() -> np.ndarray:
        f = basis.frequencies_hz
        return f[band.keeps(f)]
    now = int(np.sum(kept() <= hz * (1.0 + 1e-12)))
    target = min(max(now + 4, (3 * now) // 2), limit, basis.n_dof - 2 if not basis.dense
                 else basis.n_dof)
    if target <= now:
        return None
    if not basis.complete and basis.count < target:
        count = min(2 * target, limit, basis.n_dof - 2)
        if budget is not None and not budget.affords(modes_work(basis.model,
                                                                basis.to_solve(count))):
            return None
        basis.ensure_count(count)
    freqs = kept()
    if freqs.size <= now:
        return None
    return float(freqs[min(target, freqs.size) - 1])


def predicted_simulation(scene: Scene, config: SimulationConfig) -> Simulation:
    """
    Return ``modal.auto``'s plan as its prediction gives it, unmeasured (no pilot run).

    What the automatic choice ran before it measured its plans: the benchmark's baseline for
    what measuring adds (``modal_spring_bench --suite auto``).
    """
    if not (config.auto and config.method == 'modal'):
        raise ValueError("a predicted plan is modal.auto's: it needs auto and method modal")
    model = MassSpringModel(scene)
    return _automatic(model, ModalBasis(model), config.validate(), measured=False)


def build_simulation(scene: Scene, config: SimulationConfig, *,
                     progress: Progress | None = None, allow_unstable: bool = False,
                     worker: WorkerProcess | None = None,
                     samples: SampleStore | None = None,
                     memory_available: int | None = None) -> Simulation:
    """
    Scene + options -> a simulation at rest at t = 0.

    ``worker`` and ``samples`` (where spring samples are kept between runs): see
    :class:`ModalBasis`; a run rebuilt on its basis keeps them. ``memory_available`` (bytes,
    what the machine has): a run estimated beyond it is refused before any stage runs
    (:mod:`~modal_spring_ros.core.memory_estimate`); None: not checked.

    With ``config.anchor`` ``topic`` or ``tf`` the scene's clamp follows poses given to the
    model's :class:`~modal_spring_ros.core.motion.clamp_follower.ClampFollower` (``model.motion``:
    input state, the run's) instead of the scene's own motion.

    :raises SceneError: a mechanism (the stiffness is singular on the free DOF), or a run that
        would not fit in ``memory_available`` (:class:`MemoryLimitError`, before any of it).
    :raises BandError: impossible filter band.
    :raises UnstableStepError: explicit stepping above ``2 / omega_max`` (unless allowed).
    :raises ConfigError: other bad options (method, integrator, dt, ...).
    """
    config.validate()
    if memory_available is not None:
        check_run_memory(scene, config, memory_available)
    follower = None
    if config.anchor in POSE_SOURCES:  # the clamp follows poses (from t = 0: at its rest pose)
        rest = np.asarray(scene.rest_positions, dtype=float)
        fixed = np.flatnonzero(scene.fixed)
        clamp = rest[fixed] if fixed.size else rest
        reach = max(float(np.max(np.ptp(rest, axis=0))), REACH_MIN_M)
        follower = ClampFollower(config.follow_hz, scene.axes, home=clamp.mean(axis=0),
                                 reach_m=reach)
    model = MassSpringModel(scene, follower)
    first = min(INITIAL_MODES, config.max_modes or INITIAL_MODES)  # no more than the run may use
    basis = ModalBasis(model, initial_modes=first, progress=progress, worker=worker,
                       samples=samples)
    sim = rebuild(model, basis, config)
    if not allow_unstable:
        sim.check_stable()
    return sim

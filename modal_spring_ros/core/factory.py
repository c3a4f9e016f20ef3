"""
Build a ready-to-step simulation from a scene and a :class:`SimulationConfig`.

The command-line tools, the ROS node, the re-simulation of bags and the benchmark all go
through :func:`build_simulation`, so a run described by the same configuration is the same run
everywhere (bit for bit: the engine is deterministic).
"""
from __future__ import annotations

import dataclasses
import math

from modal_spring_ros.core.basis import ModalBasis, Progress
from modal_spring_ros.core.basis_choice import choose_basis
from modal_spring_ros.core.clamp_follower import ClampFollower
from modal_spring_ros.core.config import (AUTO_DT_SAFETY, DEFAULT_REFRESH, SAMPLE_MIN_SPRINGS,
                                          SimulationConfig)
from modal_spring_ros.core.mode_selection import (choose_modes, choose_refresh, choose_step, SHARE,
                                                  STABILITY_SAFETY)
from modal_spring_ros.core.model import MassSpringModel
from modal_spring_ros.core.scene import Scene
from modal_spring_ros.core.simulations import (DEFAULT_MAX_MODES, FullSimulation, ModalSimulation,
                                               Simulation)
from modal_spring_ros.core.simulations.coordinates import AddedCoordinateBank
from modal_spring_ros.core.worker import WorkerProcess


def rebuild(model: MassSpringModel, basis: ModalBasis, config: SimulationConfig) -> Simulation:
    """
    Return a new simulation (at rest) of the same scene and basis with other settings.

    With ``config.auto`` (modal), the fewest modes meeting ``config.tolerance`` are kept and,
    unless ``config.dt`` is given, the step follows from them, and unless
    ``config.force_refresh`` is given, so does the spring-force refresh; the basis (rest modes
    or their derivatives) is chosen by its predicted error and cost
    (:mod:`~modal_spring_ros.core.basis_choice`) in place of ``config.basis``, and so are the
    forces in place of ``config.forces``: sampled springs on large scenes, refreshed ones in
    small deformation, every spring on every step beyond it. The choice is the
    simulation's ``mode_choice``.
    """
    config.validate()
    dt = config.dt or model.scene.default_dt
    if config.method == 'modal':
        choice = None
        forces = config.forces
        refresh = config.force_refresh or (DEFAULT_REFRESH if forces == 'refreshed' else 1)
        kind = config.basis
        bank = AddedCoordinateBank(basis, config.derivative_directions, basis.progress)
        if config.auto:
            choice = choose_modes(model, basis, config.band, config.tolerance,
                                  max_modes=config.max_modes or DEFAULT_MAX_MODES)
            chosen = choose_basis(model, basis, choice.modes, SHARE * config.tolerance,
                                  lambda keep: bank.for_band(keep)[1])
            choice = dataclasses.replace(choice, basis=chosen)
            kind = chosen.kind
            dt = config.dt or choose_step(choice, config.integrator, config.tolerance,
                                          model.scene.damping)
            forces = ('sampled' if model.scene.n_springs >= SAMPLE_MIN_SPRINGS else
                      'refreshed' if chosen.small else 'exact')
            refresh = config.force_refresh or (
                choose_refresh(choice.highest_hz, dt) if forces == 'refreshed' else 1)
        sim: Simulation = ModalSimulation(
            model, basis, config.band, dt=dt or 1e-3, integrator=config.integrator,
            transition_s=config.transition_s, max_modes=config.max_modes,
            strain_limit=config.strain_limit,
            highest_hz=choice.highest_hz if choice else None, force_refresh=refresh,
            mode_choice=choice, basis_kind=kind,
            derivative_directions=config.derivative_directions, bank=bank,
            progress=basis.progress,
            sample_tolerance=config.tolerance if forces == 'sampled' else None)
        if config.dt is None and config.integrator == 'explicit':
            # the step the scene or the mode choice suggests may be beyond the stability
            # limit of what the band adds: stay within it
            limit = sim.stability_limit()
            if (dt or 0.0) >= STABILITY_SAFETY * limit:
                dt = None
    else:
        sim = FullSimulation(model, basis, config.band, dt=dt or 1e-3,
                             integrator=config.integrator, strain_limit=config.strain_limit)
    if dt is None:
        limit = sim.stability_limit()
        sim = sim.with_dt(AUTO_DT_SAFETY * limit if math.isfinite(limit) else 1e-3)
    return sim


def build_simulation(scene: Scene, config: SimulationConfig, *,
                     progress: Progress | None = None, allow_unstable: bool = False,
                     worker: WorkerProcess | None = None) -> Simulation:
    """
    Scene + options -> a simulation at rest at t = 0 (``worker``: see :class:`ModalBasis`).

    With ``config.anchor`` ``topic`` the scene's clamp follows poses given to its
    :class:`~modal_spring_ros.core.clamp_follower.ClampFollower` instead of its own motion.

    :raises SceneError: a mechanism (the stiffness is singular on the free DOF).
    :raises BandError: impossible filter band.
    :raises UnstableStepError: explicit stepping above ``2 / omega_max`` (unless allowed).
    :raises ConfigError: other bad options (method, integrator, dt, ...).
    """
    config.validate()
    if config.anchor == 'topic':  # the clamp follows poses (from t = 0: at its rest pose)
        scene = dataclasses.replace(scene, anchor_motion=ClampFollower(config.follow_hz,
                                                                       scene.axes))
    model = MassSpringModel(scene)
    basis = ModalBasis(model, progress=progress, worker=worker)
    sim = rebuild(model, basis, config)
    if not allow_unstable:
        sim.check_stable()
    return sim

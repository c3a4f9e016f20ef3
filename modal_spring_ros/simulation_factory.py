"""Build a ready-to-step simulation from user-level options (shared by every front end).

The command-line tools, the ROS node, the recorder's re-simulation and the benchmark all go
through :func:`build_simulation`, so a run described by the same :class:`SimulationConfig` is
the same run everywhere (bit for bit: the engine is deterministic).
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any

from modal_spring_ros.filter_band import FilterBand
from modal_spring_ros.mass_spring import MassSpringModel
from modal_spring_ros.modal_basis import ModalBasis, Progress
from modal_spring_ros.scene import DEFAULT_SCENE, Scene, load_scene, scene_from_dict
from modal_spring_ros.simulation import (DEFAULT_STRAIN_LIMIT, METHODS, FullSimulation,
                                         ModalSimulation, Simulation, stable_step_limit)
from modal_spring_ros.worker_process import WorkerProcess

#: Fraction of the explicit stability limit used when no time step is given.
AUTO_DT_SAFETY = 0.5


class UnstableStepError(ValueError):
    """The explicit integrator would be unstable for the modes stepped at this ``dt``."""


@dataclasses.dataclass(frozen=True)
class SimulationConfig:
    """Everything that defines a run (the scene itself aside)."""

    method: str = "modal"
    band: FilterBand = FilterBand()
    integrator: str = "explicit"
    dt: float | None = None
    transition_s: float = 0.5
    max_modes: int | None = None
    strain_limit: float = DEFAULT_STRAIN_LIMIT
    auto: bool = False                 # choose the fewest modes (and dt) for ``tolerance``
    tolerance: float = 0.01
    force_refresh: int = 0             # steps between spring evaluations; 0: 1, or auto's

    def to_dict(self) -> dict[str, Any]:
        out = dataclasses.asdict(self)
        out["band"] = dataclasses.asdict(self.band)
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "SimulationConfig":
        data = dict(data)
        band = data.pop("band", {}) or {}
        return cls(band=FilterBand(**band), **data)


#: node parameters whose change rebuilds the simulation (state and time carried over); the
#: other ``filter.*`` parameters change the band of the running one
REBUILD_PARAMETERS = frozenset({"method", "integrator", "sim.dt", "modal.auto",
                                "modal.tolerance", "modal.force_refresh"})


def band_from_parameters(values: dict[str, Any]) -> FilterBand:
    """The band described by the node's ``filter.*`` parameters."""
    if values["filter.by"] == "index":
        return FilterBand(values["filter.type"], float(values["filter.low_mode"]),
                          float(values["filter.high_mode"]), "index")
    return FilterBand(values["filter.type"], float(values["filter.low_hz"]),
                      float(values["filter.high_hz"]), "hz")


def config_from_parameters(values: dict[str, Any]) -> SimulationConfig:
    """The run the node's parameters describe (names as in the node: ``sim.dt``, ...)."""
    return SimulationConfig(
        method=values["method"], band=band_from_parameters(values),
        integrator=values["integrator"], dt=values["sim.dt"] or None,
        transition_s=values["filter.transition_s"], max_modes=values["modal.max_modes"],
        strain_limit=values["sim.strain_limit"], auto=values.get("modal.auto", False),
        tolerance=values.get("modal.tolerance", 0.01),
        force_refresh=values.get("modal.force_refresh", 0))


def rebuild(model: MassSpringModel, basis: ModalBasis, config: SimulationConfig) -> Simulation:
    """A new simulation (at rest) of the same scene and basis with other settings.

    With ``config.auto`` (modal), the fewest modes meeting ``config.tolerance`` are kept and,
    unless ``config.dt`` is given, the step follows from them, and unless
    ``config.force_refresh`` is given, so does the spring-force refresh; the choice is
    ``sim.auto``.
    """
    dt = config.dt or model.scene.default_dt
    if config.method == "modal":
        choice = None
        refresh = config.force_refresh or 1
        if config.auto:
            from modal_spring_ros.mode_selection import (choose_modes, choose_refresh,
                                                         choose_step)
            choice = choose_modes(model, basis, config.band, config.tolerance,
                                  max_modes=config.max_modes or 256)
            dt = config.dt or choose_step(choice, config.integrator, config.tolerance,
                                          model.scene.damping)
            refresh = config.force_refresh or choose_refresh(choice.highest_hz, dt)
        sim: Simulation = ModalSimulation(
            model, basis, config.band, dt=dt or 1e-3, integrator=config.integrator,
            transition_s=config.transition_s, max_modes=config.max_modes,
            strain_limit=config.strain_limit,
            highest_hz=choice.highest_hz if choice else None, force_refresh=refresh)
        sim.auto = choice
    else:
        sim = FullSimulation(model, dt=dt or 1e-3, integrator=config.integrator, basis=basis,
                             strain_limit=config.strain_limit)
    if dt is None:
        limit = sim.stability_limit()
        sim = with_dt(sim, AUTO_DT_SAFETY * limit if math.isfinite(limit) else 1e-3)
    return sim


def resolve_scene(scene: Scene | str | dict) -> Scene:
    if isinstance(scene, Scene):
        return scene
    if isinstance(scene, dict):
        return scene_from_dict(scene, source="<embedded scene>")
    return load_scene(scene or DEFAULT_SCENE)


def build_simulation(scene: Scene | str | dict, config: SimulationConfig, *,
                     progress: Progress | None = None, allow_unstable: bool = False,
                     worker: WorkerProcess | None = None) -> Simulation:
    """Scene + options -> a simulation at rest at t = 0 (``worker``: see :class:`ModalBasis`).

    Raises:
        SceneError: invalid scene (including a mechanism).
        BandError: impossible filter band.
        UnstableStepError: explicit stepping above ``2 / omega_max`` (unless allowed).
        ValueError: other bad options (method, integrator, dt).
    """
    if config.method not in METHODS:
        raise ValueError(f"method '{config.method}' must be one of {', '.join(METHODS)}")
    config.band.validate()
    scene = resolve_scene(scene)
    model = MassSpringModel(scene)
    basis = ModalBasis(model, progress=progress, worker=worker)
    sim = rebuild(model, basis, config)
    if not allow_unstable:
        check_stable(sim)
    return sim


def with_dt(sim: Simulation, dt: float) -> Simulation:
    """The same simulation (at rest) with another time step."""
    if isinstance(sim, ModalSimulation):
        out = ModalSimulation(sim.model, sim.basis, sim.band, dt=dt, integrator=sim.integrator,
                              transition_s=sim.transition_s, max_modes=sim.max_modes,
                              strain_limit=sim.strain_limit, highest_hz=sim.highest_hz,
                              force_refresh=sim.force_refresh)
        out.auto = getattr(sim, "auto", None)
        return out
    return FullSimulation(sim.model, dt=dt, integrator=sim.integrator, basis=sim.basis,
                          strain_limit=sim.strain_limit)


def check_stable(sim: Simulation, dt_name: str = "dt") -> None:
    """Refuse explicit stepping at or above ``2 / omega_max`` of the stepped modes."""
    _check_limit(sim.integrator, sim.dt, sim.stability_limit(), sim.method, dt_name)


def check_band(sim: ModalSimulation, band: FilterBand, dt_name: str = "dt") -> None:
    """Would ``band`` work in ``sim``? Computes the modes it needs; changes no state.

    Raises:
        BandError: it keeps no mode.
        UnstableStepError: its highest mode is unstable at ``sim.dt`` (explicit).
    """
    keep = sim.select_modes(band)
    limit = stable_step_limit(float(sim.basis.omega[keep].max()))
    _check_limit(sim.integrator, sim.dt, limit, "modal", dt_name)


def _check_limit(integrator: str, dt: float, limit: float, method: str, dt_name: str) -> None:
    if integrator == "explicit" and dt >= limit:
        raise UnstableStepError(
            f"{dt_name} ({dt:g} s) is at or above the explicit stability limit "
            f"2/omega_max = {limit:.4g} s of the {method} run's highest mode "
            f"({1.0 / (math.pi * limit):.4g} Hz): lower {dt_name}, keep fewer high modes "
            f"(a lower filter.high_hz), or use the 'average' integrator")

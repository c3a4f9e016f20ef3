"""
Turn a parameter request into a state change.

Validate it, do its slow part, and say which request the simulation thread must apply.

This runs in the change preparer's thread (:mod:`~modal_spring_ros.ros.changes.change_preparer`),
never in the parameter services' own. Everything that can fail or take long happens here,
before the request is queued: checking the band and the step, computing the modes a band needs
(on large scenes in the worker process), building the new simulation or the operators of the
switch. The simulation thread then only swaps prepared objects in.
"""
from __future__ import annotations

from typing import Any

from modal_spring_ros.core.bases.basis import ModalBasis
from modal_spring_ros.core.factory import rebuild
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.simulations import Simulation
from modal_spring_ros.ros.changes.requests import ChangeBand, ReplaceSimulation, Request
from modal_spring_ros.ros.parameters import (BAND_PARAMETERS, config_from_parameters,
                                             REBUILD_PARAMETERS)


class ChangePlanner:
    """Plans parameter changes for one scene (its model and basis are shared by every run)."""

    def __init__(self, model: MassSpringModel, basis: ModalBasis):
        self.model = model
        self.basis = basis

    def keeps_no_mode(self, band: FilterBand) -> str:
        """
        Say why ``band`` keeps no mode, where the modes computed already decide it ('' if not).

        They decide when the band keeps none of them and none beyond could join it (all modes
        are computed, or the band ends below the highest one computed): refused at once, not
        after the change was accepted and queued behind others.
        """
        f = self.basis.frequencies_hz
        if band.by != 'hz' or not f.size or band.keeps(f).any():
            return ''
        if not (self.basis.complete or (band.bounded_above and band.top < f[-1])):
            return ''
        return (f'filter band {band.describe()} keeps no mode (the modes up to '
                f'{f[-1]:.4g} Hz lie at {f[0]:.4g} Hz and above, none in the band)'
                if band.top < f[0] else
                f'filter band {band.describe()} keeps no mode (none of the modes from '
                f'{f[0]:.4g} to {f[-1]:.4g} Hz is in it)')

    def plan(self, values: dict[str, Any], incoming: dict[str, Any],
             running: Simulation) -> Request | None:
        """
        Validate ``incoming`` on top of ``values`` and prepare the change.

        Validate ``incoming`` on top of ``values`` against the ``running`` simulation and prepare
        the change (the new simulation, or the operators of a band switch); return the request
        the simulation thread applies, or None when the run does not change.

            ValueError (ConfigError, BandError, UnstableStepError), SceneError, WorkerError:
            the change is refused; nothing has changed.
        """
        new_values = dict(values, **incoming)
        config = config_from_parameters(new_values)
        changed = {name for name, value in incoming.items() if value != values[name]}
        delta = {name: new_values[name] for name in changed}
        if changed & REBUILD_PARAMETERS:
            sim = rebuild(self.model, self.basis, config, 'sim.dt')
            sim.check_stable('sim.dt')
            return ReplaceSimulation(simulation=sim, changed=delta)
        if changed & BAND_PARAMETERS:
            running.prepare_switch(config.band, config.transition_s, 'sim.dt')
            return ChangeBand(band=config.band, transition_s=config.transition_s,
                              changed=delta)
        return None

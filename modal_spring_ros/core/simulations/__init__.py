"""
Simulations of a scene.

A contract (:class:`Simulation`), a name-to-class registry (:data:`METHODS`), one method a module.

* ``modal`` (:class:`ModalSimulation`): the paper's method, only the modes of the band.
* ``full`` (:class:`FullSimulation`): every free DOF, the reference.
"""
from __future__ import annotations

from modal_spring_ros.core.bases.basis import DEFAULT_MAX_MODES
from modal_spring_ros.core.simulations.base import (check_step, DEFAULT_STRAIN_LIMIT,
                                                    DivergenceError, MIN_DT_S, Simulation,
                                                    SimulationStatus, stable_step_limit,
                                                    UnstableStepError)
from modal_spring_ros.core.simulations.full import FullSimulation
from modal_spring_ros.core.simulations.modal import ModalSimulation
from modal_spring_ros.core.simulations.modal_settings import ModalSettings
from modal_spring_ros.core.simulations.run_state import RunState

#: method name -> class
METHODS: dict[str, type[Simulation]] = {
    cls.method: cls for cls in (ModalSimulation, FullSimulation)}

__all__ = ['DEFAULT_MAX_MODES', 'DEFAULT_STRAIN_LIMIT', 'METHODS', 'MIN_DT_S',
           'DivergenceError', 'FullSimulation', 'ModalSettings', 'ModalSimulation', 'RunState',
           'Simulation', 'SimulationStatus', 'UnstableStepError', 'check_step',
           'stable_step_limit']

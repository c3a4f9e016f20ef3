"""
Simulations of a scene.

A contract (:class:`Simulation`), a name-to-class registry (:data:`METHODS`), one method a module.

* ``modal`` (:class:`ModalSimulation`): the paper's method, only the modes of the band.
* ``full`` (:class:`FullSimulation`): every free DOF, the reference.
"""
from __future__ import annotations

from modal_spring_ros.core.bases.basis import DEFAULT_MAX_MODES
from modal_spring_ros.core.simulations.base import (DEFAULT_STRAIN_LIMIT, DivergenceError,
                                                    Simulation, SimulationStatus)
from modal_spring_ros.core.simulations.full import FullSimulation
from modal_spring_ros.core.simulations.modal import ModalSimulation
from modal_spring_ros.core.simulations.modal_settings import ModalSettings
from modal_spring_ros.core.simulations.run_state import RunState
from modal_spring_ros.core.simulations.step_limits import (check_step, MIN_DT_S,
                                                           stable_step_limit, step_from_limit,
                                                           UnstableStepError)

#: method name -> class
METHODS: dict[str, type[Simulation]] = {
    cls.method: cls for cls in (ModalSimulation, FullSimulation)}

__all__ = ['DEFAULT_MAX_MODES', 'DEFAULT_STRAIN_LIMIT', 'METHODS', 'MIN_DT_S',
           'DivergenceError', 'FullSimulation', 'ModalSettings', 'ModalSimulation', 'RunState',
           'Simulation', 'SimulationStatus', 'UnstableStepError', 'check_step',
           'stable_step_limit', 'step_from_limit']

"""
How a modal run steps: the settings of a :class:`~.modal.ModalSimulation`, in one typed object.

What the run is given (its step, integrator, damping, fade, mode cap, strain limit, highest
mode, force model and basis) apart from the objects it works on (scene, basis, band) and the
ones it shares with other runs (the automatic choice that made it, the bank of added
coordinates, a progress callback). ``dataclasses.replace`` gives the same run with one setting
changed (``with_dt``).
"""
from __future__ import annotations

import dataclasses

from modal_spring_ros.core.bases.derivatives import DEFAULT_DIRECTIONS
from modal_spring_ros.core.forces import ForceOptions
from modal_spring_ros.core.model.scene import Damping
from modal_spring_ros.core.simulations.base import DEFAULT_STRAIN_LIMIT
from modal_spring_ros.core.simulations.coordinates import BASES
import numpy as np


@dataclasses.dataclass(frozen=True)
class ModalSettings:
    """
    The settings of a modal run (checked when the run is built).

    ``dt``: the step, s. ``integrator``: a name of
    :data:`~modal_spring_ros.core.integrators.INTEGRATORS`. ``damping``: None for the scene's.
    ``transition_s``: how long a band change fades, s. ``max_modes``: the most rest modes
    computed (None: every mode on a small scene, ``DEFAULT_MAX_MODES`` on a large one).
    ``strain_limit``: a spring strain treated as divergence. ``highest_hz``: modes above it are
    never stepped (the automatic mode choice sets it). ``forces``: how the spring forces are
    evaluated (a force model of :data:`~modal_spring_ros.core.forces.FORCES`). ``basis_kind``:
    ``rest`` (the paper's rest modes) or ``derivatives`` (each band also steps
    ``derivative_directions`` modal-derivative directions and the static load vectors).
    ``step_share``: when set, ``dt`` becomes this share of the stability limit of what the band
    steps, found before the run is built (``dt`` stays where nothing limits the step).
    """

    dt: float
    integrator: str = 'explicit'
    damping: Damping | None = None
    transition_s: float = 0.5
    max_modes: int | None = None
    strain_limit: float = DEFAULT_STRAIN_LIMIT
    highest_hz: float | None = None
    forces: ForceOptions = ForceOptions()
    basis_kind: str = 'rest'
    derivative_directions: int = DEFAULT_DIRECTIONS
    step_share: float | None = None

    def validate(self) -> 'ModalSettings':
        """Check the basis settings (the rest is checked by what uses it); returns self."""
        if self.basis_kind not in BASES:
            raise ValueError(f"basis '{self.basis_kind}' must be one of {', '.join(BASES)}")
        directions = self.derivative_directions
        if not (isinstance(directions, (int, np.integer)) and directions >= 1):
            raise ValueError(f'derivative directions ({directions}) must be a whole number, '
                             'at least 1')
        return self

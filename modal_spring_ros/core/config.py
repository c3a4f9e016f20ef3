"""
What defines a run (the scene aside), and the rules its values must meet.

:class:`SimulationConfig` is the one place those rules live. Front ends only map their own
names onto its fields (``--dt`` on the command line, ``sim.dt`` in the node), so that an error
names what the user typed: :meth:`SimulationConfig.validate` takes that mapping.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any, Mapping

from modal_spring_ros.core.auto.budget import PLANNING_SHARE
from modal_spring_ros.core.bases.derivatives import DEFAULT_DIRECTIONS
from modal_spring_ros.core.bases.mode_selection import DEFAULT_TOLERANCE
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.forces import FORCES
from modal_spring_ros.core.integrators import INTEGRATORS
from modal_spring_ros.core.motion.clamp_follower import DEFAULT_FOLLOW_HZ
from modal_spring_ros.core.simulations import DEFAULT_STRAIN_LIMIT, METHODS, MIN_DT_S
from modal_spring_ros.core.simulations.coordinates import BASES

#: Fraction of the explicit stability limit used when no time step is given.
AUTO_DT_SAFETY = 0.5
#: Largest spring strain still in the small-deformation regime the modal basis assumes.
DEFAULT_STRAIN_WARNING = 0.1
#: Range of the number of derivative directions a band may add.
MIN_DIRECTIONS, MAX_DIRECTIONS = 1, 200
#: Default fade time of modes leaving or entering the band, s.
DEFAULT_TRANSITION_S = 0.5
#: Steps between exact evaluations of refreshed forces when neither it nor modal.auto says.
DEFAULT_REFRESH = 10
#: Scenes with at least this many springs get sampled forces from the automatic choice (on
#: smaller ones training costs more than it saves).
SAMPLE_MIN_SPRINGS = 20_000
#: Where the clamp's motion comes from: the scene's anchor_motion, or a stream of poses (a
#: topic's, or a TF frame's).
ANCHOR_SOURCES = ('scene', 'topic', 'tf')
#: the sources whose poses the clamp follows
POSE_SOURCES = ('topic', 'tf')
#: Highest bandwidth a clamp follows poses with, Hz.
MAX_FOLLOW_HZ = 100.0
#: Longest run the automatic choice promises its tolerance over, s (a day).
MAX_HORIZON_S = 86_400.0
#: Simulated seconds between two watched windows of an automatic plan, by default (0: not
#: watched; :mod:`~modal_spring_ros.core.auto.watch.run_watch`).
DEFAULT_WATCH_S = 10.0


class ConfigError(ValueError):
    """A setting out of range; the message names it as the user wrote it."""


@dataclasses.dataclass(frozen=True)
class SimulationConfig:
    """Everything that defines a run (the scene itself aside)."""

    method: str = 'modal'
    band: FilterBand = FilterBand()
    integrator: str = 'explicit'
    dt: float | None = None            # None: the scene's, else from the stability limit
    transition_s: float = DEFAULT_TRANSITION_S
    max_modes: int | None = None       # None: every mode (dense scenes) or DEFAULT_MAX_MODES
    strain_limit: float = DEFAULT_STRAIN_LIMIT
    auto: bool = False                 # choose the fewest modes (and dt) for ``tolerance``
    tolerance: float = DEFAULT_TOLERANCE
    force_refresh: int = 0             # steps between spring evaluations; 0: 1, or auto's
    basis: str = 'derivatives'         # modal: rest modes, or rest modes and their derivatives
    derivative_directions: int = DEFAULT_DIRECTIONS
    forces: str = 'exact'              # spring forces: a FORCES model (exact, refreshed, ...)
    anchor: str = 'scene'              # the clamp moves as the scene says, or follows poses
    follow_hz: float = DEFAULT_FOLLOW_HZ  # bandwidth of the filter poses are followed through
    horizon_s: float | None = None     # the run auto's tolerance holds over; None: the scene's
    watch_s: float | None = None       # auto's plan re-measured every this many s; 0: never;
    #                                    None: every DEFAULT_WATCH_S within a share of its work
    planning_share: float | None = PLANNING_SHARE  # what auto's planning may spend, as a share
    #                                    of the full run over ``horizon_s`` (a run of that
    #                                    length); None, or no ``horizon_s``: not budgeted

    def validate(self, names: Mapping[str, str] | None = None) -> 'SimulationConfig':
        """
        Check every rule.

        Raise :class:`ConfigError` (or a ``BandError`` for the band) naming the setting as
        ``names`` calls it (the field name by default). Returns self.
        """
        names = names or {}

        def name(field: str) -> str:
            return names.get(field, field)

        for field, choices in (('method', METHODS), ('integrator', INTEGRATORS),
                               ('basis', BASES), ('forces', FORCES),
                               ('anchor', ANCHOR_SOURCES)):
            value = getattr(self, field)
            if value not in choices:
                raise ConfigError(f"{name(field)} '{value}' must be one of "
                                  f"{', '.join(choices)}")
        if self.dt is not None and not (math.isfinite(self.dt) and self.dt >= MIN_DT_S):
            raise ConfigError(f"{name('dt')} ({self.dt}) must be a finite number of seconds, "
                              f'at least {MIN_DT_S:g} s (a smaller step does not advance '
                              'time)')
        if not (math.isfinite(self.transition_s) and self.transition_s >= 0.0):
            raise ConfigError(f"{name('transition_s')} ({self.transition_s}) must be a finite "
                              'number of seconds, not negative')
        if self.max_modes is not None and self.max_modes < 1:
            raise ConfigError(f"{name('max_modes')} ({self.max_modes}) must be at least 1")
        if not (math.isfinite(self.strain_limit) and self.strain_limit > 0.0):
            raise ConfigError(f"{name('strain_limit')} ({self.strain_limit}) must be positive")
        if not 0.0 < self.tolerance < 1.0:
            raise ConfigError(f"{name('tolerance')} ({self.tolerance}) must be between 0 and 1")
        if not MIN_DIRECTIONS <= self.derivative_directions <= MAX_DIRECTIONS:
            raise ConfigError(f"{name('derivative_directions')} ({self.derivative_directions}) "
                              f'must be from {MIN_DIRECTIONS} to {MAX_DIRECTIONS}')
        if not (math.isfinite(self.follow_hz) and 0.0 < self.follow_hz <= MAX_FOLLOW_HZ):
            raise ConfigError(f"{name('follow_hz')} ({self.follow_hz}) must be a number of Hz "
                              f'above 0 and at most {MAX_FOLLOW_HZ:g}')
        if self.horizon_s is not None and not (math.isfinite(self.horizon_s)
                                               and 0.0 < self.horizon_s <= MAX_HORIZON_S):
            raise ConfigError(f"{name('horizon_s')} ({self.horizon_s}) must be a number of "
                              f'seconds above 0 and at most {MAX_HORIZON_S:g}')
        if self.watch_s is not None and not (math.isfinite(self.watch_s)
                                             and 0.0 <= self.watch_s <= MAX_HORIZON_S):
            raise ConfigError(f"{name('watch_s')} ({self.watch_s}) must be a number of seconds "
                              f'from 0 (not watched) to {MAX_HORIZON_S:g}')
        if self.planning_share is not None and not (math.isfinite(self.planning_share)
                                                    and 0.0 < self.planning_share <= 1.0):
            raise ConfigError(f"{name('planning_share')} ({self.planning_share}) must be a share "
                              'above 0 and at most 1 of the full run')
        if self.auto and self.method != 'modal':
            raise ConfigError(f"{name('auto')} chooses modes: it needs {name('method')} modal")
        if self.band.shaped and self.method != 'modal':
            raise ConfigError(f"a filter shape ({name('order')}, {name('gains')}, "
                              f"{name('damping')}) acts on modes: it needs {name('method')} "
                              'modal')
        if self.band.shaped and self.auto:
            raise ConfigError(f"{name('auto')} chooses modes for keep-or-drop bands: a filter "
                              f"shape ({name('order')}, {name('gains')}, {name('damping')}) "
                              f"needs {name('auto')} off")
        if self.force_refresh < 0:
            raise ConfigError(f"{name('force_refresh')} ({self.force_refresh}) must be at "
                              'least 1 step (or 0: the default)')
        self.band.validate(names)
        return self

    def to_dict(self) -> dict[str, Any]:
        out = dataclasses.asdict(self)
        out['band'] = dataclasses.asdict(self.band)
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> 'SimulationConfig':
        """
        Return a configuration as :meth:`to_dict` wrote it.

        One written before the basis was a setting was a run of rest modes; one written before
        automatic plans were watched while running was not watched; one written before
        planning was budgeted was planned unbudgeted.
        """
        data = dict(data)
        data.setdefault('basis', 'rest')
        data.setdefault('watch_s', 0.0)      # recorded before runs were watched: not watched
        data.setdefault('planning_share', None)
        band = data.pop('band', {}) or {}
        return cls(band=FilterBand(**band), **data)

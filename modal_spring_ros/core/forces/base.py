"""
The force model contract: what every way of evaluating the spring forces offers.

A force model gives the generalised force ``Q(q, t)`` on one set of coordinates (the springs of
eq. 20 projected on them, plus the loads), says what it costs (the share of its calls that
evaluated every spring) and how accurate it was (a typed :class:`ForceReport`, never text a
caller parses), and is built from typed :class:`ForceOptions` and a :class:`ForceContext` (the
set's exact forces, its frequencies and damping, the step, and the services a model may use:
progress, a worker process, a sample store). What it needs trained or cached it says with
``trained``: a simulation builds such a model for a settled band only (a fade is too short
to pay for training) and uses :meth:`ForceOptions.untrained` meanwhile.

A new force model is one module with a subclass and one line in
:data:`modal_spring_ros.core.forces.FORCES`.
"""
from __future__ import annotations

import abc
import dataclasses
import math
from typing import Callable, ClassVar, Mapping, Protocol

from modal_spring_ros.core.worker import WorkerProcess
import numpy as np


@dataclasses.dataclass(frozen=True)
class ForceOptions:
    """
    How a run's spring forces are evaluated.

    ``model``: a :data:`~modal_spring_ros.core.forces.FORCES` name. ``refresh``: steps between
    evaluations of every spring (refreshed forces). ``tolerance``: the relative force error a
    model is trained within and falls back to exact forces beyond (inf: never falls back).
    """

    model: str = 'exact'
    refresh: int = 1
    tolerance: float = math.inf

    def validate(self) -> 'ForceOptions':
        """Check the values that do not depend on the model; returns self."""
        if not (isinstance(self.refresh, (int, np.integer)) and self.refresh >= 1):
            raise ValueError(f'force refresh ({self.refresh}) must be a whole number of steps, '
                             'at least 1')
        if not self.tolerance > 0.0:  # NaN too
            raise ValueError(f'force tolerance ({self.tolerance}) must be above 0')
        return self

    def untrained(self) -> 'ForceOptions':
        """Return the options without training: refreshed forces if they refresh, else exact."""
        return dataclasses.replace(self, model='refreshed' if self.refresh > 1 else 'exact')


@dataclasses.dataclass(frozen=True)
class ForceReport:
    """What a force model says about itself (plain values, for diagnostics and summaries)."""

    model: str                  # the registry name of the model that ran
    description: str            # how the springs are evaluated, as text
    interval: int = 1           # steps between evaluations of every spring (1: every step)
    error: float | None = None  # largest measured force error since the last restart (None:
    #                             every spring on every step, nothing to measure)
    fell_back: bool = False     # it passed its tolerance and evaluates every spring from then on


class SampleStore(Protocol):
    """Where samples are kept between runs (a front end's: the core keeps none itself)."""

    def load(self, key: str) -> Mapping[str, np.ndarray] | None:
        """
        Return the arrays stored under ``key``, or None when there are none.

        :raises CacheEntryError: the entry cannot be read.
        """

    def save(self, key: str, arrays: Mapping[str, np.ndarray]) -> None:
        """Keep ``arrays`` under ``key`` (a store that cannot write only costs training again)."""

    def discard(self, key: str) -> None:
        """Remove the entry under ``key``, if any."""

    def where(self, key: str) -> str:
        """Return where the entry under ``key`` lives, for messages."""


@dataclasses.dataclass(frozen=True, eq=False)
class ForceContext:
    """What building a force model for one set of coordinates may use."""

    exact: 'ForceModel'         # the exact model (:class:`~modal_spring_ros.core.forces.exact.
    #                             ExactForces`) on these coordinates: the others build on it
    phi: np.ndarray             # (free DOF, m) the coordinates' shapes
    omega2: np.ndarray          # (m,) squared angular frequencies of the coordinates
    damping: np.ndarray         # (m,) their modal damping coefficients
    dt: float                   # the run's step, s
    strain_limit: float = math.inf  # divergence: a step past it must know its exact strain
    progress: Callable[[str], None] | None = None
    worker: WorkerProcess | None = None   # long training runs there, off the caller's GIL
    samples: SampleStore | None = None    # where trained samples are kept (None: nowhere)


class ForceModel(abc.ABC):
    """
    ``Q(q, t)`` on one set of coordinates: spring forces (however evaluated) plus the loads.

    :ivar last_max_strain: largest spring strain at the last call (exact, or an upper bound
        never below it): what divergence detection sees.
    """

    #: registry name
    name: ClassVar[str]
    #: needs something trained (or cached) per set of coordinates before it runs
    trained: ClassVar[bool] = False
    last_max_strain: float = 0.0

    @classmethod
    @abc.abstractmethod
    def build(cls, context: ForceContext, options: ForceOptions) -> 'ForceModel':
        """Return the model for the coordinates of ``context`` (options validated)."""

    @abc.abstractmethod
    def __call__(self, q: np.ndarray, t: float) -> np.ndarray:
        """Return the total generalised force at ``q``, ``t`` (sets ``last_max_strain``)."""

    @abc.abstractmethod
    def loads(self, t: float) -> np.ndarray:
        """Return the generalised gravity and base-excitation load at ``t`` (exact)."""

    @abc.abstractmethod
    def gravity(self) -> np.ndarray:
        """Return the generalised gravity load alone."""

    @abc.abstractmethod
    def report(self) -> ForceReport:
        """Return what the model says about itself."""

    def restart(self) -> None:
        """Forget what past calls left behind (the state was set from outside)."""

    @property
    def evaluated_share(self) -> float:
        """Return the share of calls so far that evaluated every spring (its cost; 1: all)."""
        return 1.0

"""
How fast a run's motion amplifies a small difference: a twin from a hair-perturbed state.

A step's error is a promise about a trajectory, and some motions keep none: a soft solid turned
far, a skin crumpling under its weight. Two runs of such a motion that start a hair apart part
exponentially, so halving the step moves the run as much as the step's own error, no run is
within the tolerance of another for long, and a plan checked over its start (before the growth
shows) prints an error it will not keep. A start that agrees with its modes says nothing of it.

:class:`Growth` measures it where the run is: a twin of the run, from the run's state with a
displacement perturbed by ``RELATIVE`` of its size, is stepped beside a copy of the run over one
window's first ``WINDOW_S`` (a hair's difference that grows stops growing once it is as large
as the motion: measured over longer, a chaotic motion's growth would be hidden by its
saturation), and the distance between the two (free-DOF displacement, at each sample) is
compared between the span's first and last quarters. A motion that converges keeps or damps the
distance (at most 0.6 e-folds per second measured on the random, resonant and stiff scenes of
the benches); a chaotic one multiplies it (6-15 e-folds per second on a soft ring turned +-60
degrees, 44-48 on a soft mesh turned 90 degrees). Beyond ``AMPLIFYING_PER_S`` the motion is said
to amplify its differences: its error is not bounded by the tolerance. The run watch
(:mod:`~.run_watch`) steps a twin in each window; planning steps one from rest
(:func:`start_growth`) before it would search the whole window for a step no motion that
amplifies from its start has. Where the run is stepped one step at a time by its caller
(``modal_spring_sim``), the twin is stepped beside the run itself (:class:`TwinBeside`): the run
is its own copy, and a window costs the twin alone.
"""
from __future__ import annotations

import math
from typing import Callable

from modal_spring_ros.core.simulations import DivergenceError, RunState, Simulation
import numpy as np

#: The twin's displacement perturbation, relative to the run's rms displacement.
RELATIVE = 1e-7
#: The displacement scale where the run is at rest, m (the twin still starts apart).
FLOOR_M = 1e-6
#: Growth of the twin's distance beyond which a motion amplifies its differences, e-folds per
#: second (doubling in 0.35 s): three times the most measured on motions that converge.
AMPLIFYING_PER_S = 2.0
#: The perturbation's direction is drawn from this seed: the same run gives the same twin.
SEED = 0
#: The span a twin is stepped over, s, on at least ``MIN_SAMPLES`` samples.
WINDOW_S = 0.25
MIN_SAMPLES = 4
#: Samples of a twin stepped by :func:`start_growth`.
SAMPLES = 16
#: What an amplifying motion means for a run's error.
UNBOUNDED = ('the motion amplifies its differences (chaotic): no run keeps within the tolerance '
             'of another for long, and the error printed for this one is not bounded')


def perturbed(state: RunState) -> RunState:
    """Return ``state`` with its displacement perturbed by a hair (``RELATIVE`` of its rms)."""
    u = state.displacement()
    direction = np.random.default_rng(SEED).standard_normal(u.shape)
    scale = max(float(np.sqrt(np.mean(u ** 2))) if u.size else 0.0, FLOOR_M)
    size = float(np.sqrt(np.mean(direction ** 2))) if u.size else 1.0
    return state.displaced(direction * (RELATIVE * scale / size))


class Growth:
    """The distance between a run and its twin at each sample of a window, and its growth rate."""

    def __init__(self, sample_s: float):
        self.sample_s = float(sample_s)
        self._distances: list[float] = []
        self.diverged = False

    def add(self, run: np.ndarray, twin: np.ndarray) -> None:
        """Record one sample: the two free-DOF displacements."""
        self._distances.append(float(np.linalg.norm(run - twin)))

    @property
    def samples(self) -> int:
        return len(self._distances)

    def rate(self) -> float:
        """
        Return the distance's growth rate, e-folds per second (nan: not measured).

        From the rms distance over the window's first quarter of samples to its last (their
        centres three quarters of the window apart); inf where the twin diverged and the run
        did not (a hair's difference grew to a blow-up).
        """
        if self.diverged:
            return math.inf
        d = np.asarray(self._distances)
        quarter = d.size // 4
        if quarter < 1:
            return math.nan
        first = float(np.sqrt(np.mean(d[:quarter] ** 2)))
        last = float(np.sqrt(np.mean(d[-quarter:] ** 2)))
        if not (first > 0.0 and math.isfinite(last)):
            return math.nan
        if last == 0.0:
            return -math.inf
        return math.log(last / first) / ((d.size - quarter) * self.sample_s)


def twin_samples(sample_s: float, samples: int) -> int:
    """Return how many of a window's ``samples`` (``sample_s`` apart) its twin is stepped over."""
    return min(samples, max(MIN_SAMPLES, math.ceil(WINDOW_S / sample_s - 1e-9)))


class TwinBeside:
    """
    A twin stepped beside the run itself, sample by sample: one shadow where a copy made two.

    Made from ``run``'s state moved by a hair (in ``twin``, a run of the same method, taken
    over); :meth:`observe` sees the run after each of its steps and, every ``sample_s`` of
    them, steps the twin to the same time and measures their distance, over ``samples`` samples.
    """

    def __init__(self, run: Simulation, sample_s: float, samples: int, twin: Simulation):
        state = RunState.of(run)
        self.start_s = state.time
        self.twin = twin
        self.twin.take_over(perturbed(state))
        self._run, self._from = run, run.steps
        self._per = max(1, int(round(sample_s / run.dt)))
        self._samples = samples
        self.growth = Growth(self._per * run.dt)

    @property
    def done(self) -> bool:
        return self.growth.diverged or self.growth.samples >= self._samples

    @property
    def span_s(self) -> float:
        """Return the simulated time the samples taken span, s."""
        return self.growth.samples * self.growth.sample_s

    def follows(self, run: Simulation) -> bool:
        """Tell whether ``run`` is the run the twin is beside, no sample skipped (not reset)."""
        return (run is self._run
                and 0 <= run.steps - self._from <= self._per * (self.growth.samples + 1))

    def observe(self, run: Simulation) -> bool:
        """Take a sample where ``run`` has reached one; tell whether the window is done."""
        if run.steps - self._from == self._per * (self.growth.samples + 1) and not self.done:
            try:
                twin = stepped_displacement(self.twin, self._per)
            except DivergenceError:
                self.growth.diverged = True
            else:
                self.growth.add(run.displacement(), twin)
        return self.done


def stepped_displacement(run: Simulation, steps: int) -> np.ndarray:
    """Step ``run`` by ``steps``; return its free-DOF displacement (a non-finite one diverged)."""
    run.step(steps)
    u = run.displacement()
    if not np.isfinite(u).all():
        raise DivergenceError('non-finite state', run.time, run.steps)
    return u


def start_growth(make: Callable[[], Simulation]) -> float:
    """
    Return how fast a hair's difference grows over a run's first ``WINDOW_S`` from rest.

    ``make()`` builds the run at rest; it is stepped twice, once from a perturbed rest. nan
    where the run itself diverged.
    """
    run, twin = make(), make()
    twin.take_over(perturbed(RunState.of(run)))
    per = max(1, int(round(WINDOW_S / SAMPLES / run.dt)))
    growth = Growth(per * run.dt)
    for _ in range(SAMPLES):
        try:
            run.step(per)
        except DivergenceError:
            return math.nan
        try:
            twin.step(per)
        except DivergenceError:
            growth.diverged = True
            break
        growth.add(run.displacement(), twin.displacement())
    return growth.rate()


def amplifies(rate: float) -> bool:
    """Tell whether a growth ``rate`` (e-folds per second) means the motion amplifies."""
    return not math.isnan(rate) and rate >= AMPLIFYING_PER_S


def describe_rate(rate: float) -> str:
    """Say how a hair's difference grew at ``rate`` (e-folds per second)."""
    if math.isnan(rate):
        return "the growth of a hair's difference not measured"
    if math.isinf(rate) and rate > 0:
        return 'a hair-perturbed twin diverged'
    if amplifies(rate):
        return f"a hair's difference grew e-fold every {1.0 / rate:.2g} s"
    return f"a hair's difference did not grow ({rate:+.2g} e-folds per second)"

"""
The error a full run's step is predicted to make, from every mode and the integrator's own step.

A start checked by step doubling does not see an error that grows later (a mode's period error
drifts its phase a little more every period), so a small scene's default step is also judged
before it is run. Every mode is stepped twice over the run, exactly, under the scene's loads
projected on it (gravity, the clamp's shake or turn: the state-independent loads of the clamp's
frame, linear between instants): once with its own frequency and damping, once with those the
integrator's step gives it. Those are read from the integrator itself (one step of every mode at
once, the eigenvalues of that step's map: the period error and the numerical damping;
:mod:`~modal_spring_ros.core.integrators.mode_step`), so an
integrator added to the registry is predicted without a formula of its own. The relative L2
difference of the two displacements over the run's samples, in the clamp's frame as runs are
measured (:mod:`~modal_spring_ros.core.auto.measured_error`), is the step's predicted error.

It is a linear prediction: the springs' nonlinearity and the frame's Coriolis and centrifugal
coupling are left out, and nothing is predicted where the modes' own motion is no small
displacement (``LINEAR_REACH``). On the promise suite's random scenes it was 0.75-1.7 times the
measured error of the default step (over any start: 0.8-1.2 times), so a full run takes the step
it predicts only where a check of its start, against its run at half the step, agrees
(:func:`~modal_spring_ros.core.auto.unplanned_full.unplanned_full`).
What the static response carries (gravity's sag, a slow drive's quasi-static part) has no period
error, and a damped mode's error decays with it: the period error's growth alone,
weighted by the modes' static shares (:func:`~modal_spring_ros.core.bases.mode_selection.
choose_step`), flagged damped scenes whose default step met the tolerance by up to 7 times.
"""
from __future__ import annotations

import dataclasses
import math

from modal_spring_ros.core.auto.measured_error import (drift_growth, trajectory_error,
                                                       WINDOW_ALLOWANCE, worst_window)
from modal_spring_ros.core.bases.basis import ModalBasis
from modal_spring_ros.core.integrators.mode_step import scheme_frequencies
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.motion.frame_loads import FrameLoads
from modal_spring_ros.core.threads import stepping_threads
import numpy as np
import scipy.linalg

#: Instants the modes are stepped at over the run, at most (the loads are sampled there).
MAX_INSTANTS = 1500
#: Instants per period of the fastest drive term, at least; and the longest interval, s.
PER_DRIVE_PERIOD, LONGEST_INTERVAL_S = 16, 0.02
#: A step's error grows as its square (second-order schemes): a step within a tolerance is
#: found from one prediction, then confirmed once.
ORDER = 2
#: Predictions made at most while looking for it, and how far under the order's step each goes.
MAX_PREDICTIONS, SETTLE = 4, 0.97
#: A longer step than the default is predicted only where it is this much longer.
LONGER_WORTH = 0.05
#: A scene beyond the dense limit is predicted from the modes it has (its lowest) where every
#: drive term is at least this many times slower than the highest of them: the modes left out
#: then follow the drive quasi-statically (a mode driven at a quarter of its frequency responds
#: within 7 % of its static response), with no period error of their own beyond the start's
#: transient, which a check of the start measures (:meth:`StepPrediction.confirmed`).
QUASI_STATIC = 4.0
#: A start measured within this many times its predicted error agrees with the prediction (over
#: starts of random scenes the prediction was 0.8-1.2 times the measured error).
AGREEMENT = 1.5
#: Where the modes' exact motion moves springs' ends apart by this share of their length or
#: more (at the ``REACH_INSTANTS`` instants it is largest), it is no small displacement, and
#: nothing is predicted from them (over 100 random scenes: 0.52-1.56 times the measured error
#: below it, 0.34-4.5 times at or beyond it, four of ten diverging at their default step).
LINEAR_REACH, REACH_INSTANTS = 1.0, 16
#: A start off its prediction by more than this many times moved beyond the modes' linear
#: motion (large strain, buckling): it never confirms the prediction, and no step's error is
#: scaled from another's there.
NONLINEAR = 10.0


def predicting_hz(model: MassSpringModel) -> float:
    """Return how high a scene's lowest modes must reach to predict its full run's step, Hz."""
    drive = model.motion.frequencies_hz
    return QUASI_STATIC * (float(drive.max()) if drive.size else 0.0)


def predicts(model: MassSpringModel, basis: ModalBasis) -> bool:
    """Tell whether ``basis``'s modes can predict a full run's step error (``QUASI_STATIC``)."""
    if basis.complete:
        return True
    return bool(basis.count) and predicting_hz(model) <= float(basis.frequencies_hz[-1])


def _propagator(omega: np.ndarray, sigma: np.ndarray, h: float) -> np.ndarray:
    """
    Return the exact free step of ``q'' + 2 sigma q' + w0^2 q = 0`` over ``h``, per mode.

    ``omega`` is the damped frequency, ``w0^2 = omega^2 + sigma^2``: the (n, 2, 2) map of
    ``(q, q')``.
    """
    w0sq = omega ** 2 + sigma ** 2
    decay = np.exp(-sigma * h)
    c = np.cos(omega * h)
    s_over = np.where(omega * h > 1e-9, np.sin(omega * h) / np.where(omega > 0, omega, 1.0), h)
    phi = np.empty((omega.size, 2, 2))
    phi[:, 0, 0] = decay * (c + sigma * s_over)
    phi[:, 0, 1] = decay * s_over
    phi[:, 1, 0] = -decay * w0sq * s_over
    phi[:, 1, 1] = decay * (c - sigma * s_over)
    return phi


def _instants(model: MassSpringModel, horizon_s: float, least: int = 1) -> tuple[float, int]:
    """
    Return the interval the modes are stepped at, and how many (the drive sampled finely).

    At least ``least`` instants over ``horizon_s``.
    """
    drive_hz = model.motion.frequencies_hz
    fastest = float(drive_hz.max()) if drive_hz.size else 0.0
    h = LONGEST_INTERVAL_S
    if fastest > 0:
        h = min(h, 1.0 / (PER_DRIVE_PERIOD * fastest))
    count = int(min(MAX_INSTANTS, max(least, math.ceil(horizon_s / h))))
    return horizon_s / count, count


class StepErrorPredictor:
    """
    The error a full run of ``model`` over ``horizon_s`` is predicted to make at any step.

    ``basis`` holds every mode (a dense one); ``name`` is the run's integrator. The scene's loads
    on every mode and the modes' exact response are computed once; each step asked steps the
    modes again with the frequencies and damping the integrator gives them at that step.
    """

    def __init__(self, model: MassSpringModel, basis: ModalBasis, name: str, horizon_s: float,
                 least_instants: int = 1, parent: StepErrorPredictor | None = None):
        """``parent``: the run's predictor a start's shares its metric, loads and reach with."""
        self.name, self._model, self._basis = name, model, basis
        #: a start's own predictor, and its instants per sample, by (span, sample interval)
        self._starts: dict[tuple[float, float], tuple[StepErrorPredictor, int]] = {}
        self.horizon_s = horizon_s
        if parent is not None:    # its modes (the basis may have grown since: a band's solve)
            self._omega, self._damping, self.complete, self.count, self.highest_hz = (
                parent._omega, parent._damping, parent.complete, parent.count, parent.highest_hz)
            self.slowest_decay = parent.slowest_decay
        else:
            self._omega = basis.omega
            damping = model.scene.damping
            self._damping = (damping.modal_coefficients(self._omega)
                             if damping is not None else np.zeros_like(self._omega))
            self.complete, self.count = bool(basis.complete), basis.count
            self.highest_hz = float(basis.frequencies_hz[-1]) if basis.count else 0.0
            #: the slowest decay rate (1/s) an error beyond the modes can have: the modes' own,
            #: and the scene's Rayleigh terms' beyond the highest (a ratio is not counted there:
            #: where the scene is too large for every mode, the modes beyond have a fitted term)
            beyond = (damping.rayleigh_alpha + damping.rayleigh_beta * self._omega[-1] ** 2
                      if damping is not None and basis.count else 0.0)
            self.slowest_decay = 0.5 * float(min(self._damping.min(initial=math.inf), beyond))
        # the displacement's Euclidean norm from the modal coordinates: ||Phi q|| = ||R q||
        # with R^T R = Phi^T Phi (the modes are mass-normalised, not orthonormal), so a run is
        # kept as (instants, modes), whatever the scene's size
        self._metric = (parent._metric if parent is not None else
                        scipy.linalg.cholesky(basis.vectors.T @ basis.vectors, lower=False))
        self._h, count = _instants(model, horizon_s, least_instants)
        self._frame = (parent._frame if parent is not None
                       else FrameLoads(model, basis.vectors, coupling=False))
        sigma = 0.5 * self._damping
        with stepping_threads():          # many small products: one BLAS thread
            self._loads = np.array([self._frame.loads(k * self._h) for k in range(count + 1)])
            exact = self._response(np.sqrt(np.maximum(self._omega ** 2 - sigma ** 2, 0.0)),
                                   sigma, by_metric=False)
        self._exact = exact @ self._metric.T
        #: the modes' exact motion's reach where it is largest (``LINEAR_REACH``, ``.holds``)
        largest = np.argsort(np.einsum('km,km->k', self._exact, self._exact))[-REACH_INSTANTS:]
        self.reach = (parent.reach if parent is not None
                      else model.spring_reach(basis.vectors @ exact[largest].T))
        self._runs: dict[float, np.ndarray | None] = {}   # each step's run, once

    def _response(self, omega: np.ndarray, sigma: np.ndarray, by_metric: bool = True
                  ) -> np.ndarray:
        """
        Return the displacement at every instant after the first as ``R q`` (or ``q``).

        Stepped exactly with the load linear between instants (a held load's jumps would
        ring every mode, the fast ones most: a smooth drive does not, and the fast modes'
        period errors would be counted where the run has none). The ramp ``p0 + s t`` has the
        particular response ``(a + b t, b)``, ``b = s / w0^2``, ``a = (p0 - 2 sigma b) / w0^2``;
        the rest is the free step of the difference.
        """
        phi = _propagator(omega, sigma, self._h)
        w0sq = np.maximum(omega ** 2 + sigma ** 2, 1e-300)
        b = np.diff(self._loads, axis=0) / (self._h * w0sq)             # (count, n)
        a = (self._loads[:-1] - 2.0 * sigma * b) / w0sq
        # every interval's forced part at once: x1 = phi (x0 - (a, b)) + (a + b h, b)
        forced_q = a + b * self._h - phi[:, 0, 0] * a - phi[:, 0, 1] * b
        forced_v = b - phi[:, 1, 0] * a - phi[:, 1, 1] * b
        q = np.empty_like(forced_q)
        u, v = np.zeros(omega.size), np.zeros(omega.size)
        for k in range(len(q)):
            u, v = (phi[:, 0, 0] * u + phi[:, 0, 1] * v + forced_q[k],
                    phi[:, 1, 0] * u + phi[:, 1, 1] * v + forced_v[k])
            q[k] = u
        return q @ self._metric.T if by_metric else q

    def _run(self, dt: float) -> np.ndarray | None:
        """Return the modes' displacement stepped as ``dt`` steps them (None: unstable)."""
        if dt not in self._runs:
            stepped, decay = scheme_frequencies(self.name, self._omega, self._damping, dt)
            unstable = np.any(decay < -1e-9 * np.maximum(self._omega, 1.0))
            with stepping_threads():      # many small products: one BLAS thread
                self._runs[dt] = None if unstable else self._response(stepped, decay)
        return self._runs[dt]

    def predicted(self, dt: float) -> bool:
        """Say whether ``dt``'s run was stepped already (its errors cost nothing more)."""
        return dt in self._runs

    def error(self, dt: float, over_s: float | None = None) -> float:
        """
        Return the error predicted at ``dt``, as the promise has it.

        The relative L2 error over the run, or its worst ``PROMISE_WINDOW_S`` window's share of
        the window allowance where that is more (a step that meets the tolerance on average may
        not in every window). ``inf`` where the step is unstable for some mode; 0 where the
        scene has no load. ``over_s``: over the run's first ``over_s`` only, the relative L2
        error alone, on the run's instants (:meth:`sampled_error`: on a check's samples).
        """
        run = self._run(dt)
        if run is None:
            return math.inf
        if over_s is not None:
            count = min(len(run), max(1, math.ceil(over_s / self._h - 1e-9)))
            return trajectory_error(run[:count], self._exact[:count])
        whole = trajectory_error(run, self._exact)
        return max(whole, worst_window(run, self._exact, self._h) / WINDOW_ALLOWANCE)

    def sampled_error(self, dt: float, over_s: float, sample_s: float) -> float:
        """
        Return the relative L2 error predicted at ``dt`` on a check's samples.

        Every ``sample_s`` over the run's first ``over_s``, as a check of its start measures
        it: stepped on instants that divide ``sample_s`` and resolve the drive, read at the
        samples alone (read on the run's coarser instants, a start was put at 0.57 times what
        its check measured on two samples: disproved, searched at 60 times the run's cost).
        """
        if (over_s, sample_s) not in self._starts:
            samples = max(1, round(over_s / sample_s))
            per = min(_instants(self._model, sample_s)[1], max(1, MAX_INSTANTS // samples))
            self._starts[(over_s, sample_s)] = (StepErrorPredictor(
                self._model, self._basis, self.name, samples * sample_s, samples * per, self),
                per)
        start, per = self._starts[(over_s, sample_s)]
        run = start._run(dt)
        if run is None:
            return math.inf
        return trajectory_error(run[per - 1::per], start._exact[per - 1::per])


@dataclasses.dataclass(frozen=True)
class StepPrediction:
    """The longest step predicted within a tolerance, its predicted error, and its predictor."""

    step: float
    error: float
    predictor: StepErrorPredictor | None = None
    #: the interval a check's samples are taken at (None: a start read on the run's instants)
    sample_s: float | None = None

    def sampled(self, sample_s: float) -> StepPrediction:
        """Return this prediction, its starts read on samples every ``sample_s`` (as checked)."""
        return dataclasses.replace(self, sample_s=sample_s)

    def error_at(self, dt: float) -> float:
        """Return the error predicted at ``dt`` (stepped where it was, else the step's square)."""
        if self.predictor is not None and self.predictor.predicted(dt):
            return self.predictor.error(dt)
        return self.error * (dt / self.step) ** ORDER

    @property
    def holds(self) -> bool:
        """Tell whether the modes' motion is a small displacement (``LINEAR_REACH``)."""
        return self.predictor is None or self.predictor.reach < LINEAR_REACH

    def start_error(self, dt: float, over_s: float) -> float:
        """Return the error predicted at ``dt`` over the run's first ``over_s`` (nan: none)."""
        if self.predictor is None:
            return math.nan
        if self.sample_s is None:
            return self.predictor.error(dt, over_s)
        return self.predictor.sampled_error(dt, over_s, self.sample_s)

    def confirmed(self, measured: float, dt: float, over_s: float, allowed: float,
                  longer: bool = False) -> float:
        """
        Return the run's error at ``dt`` where a start's ``measured`` error confirms it, else nan.

        The start (its first ``over_s``) confirms the prediction where it is within ``allowed``
        or within ``AGREEMENT`` times what the prediction puts there (a start's transient can be
        beyond the run's tolerance where the prediction sees it too), and never where it moved
        beyond the modes (:meth:`beyond`) or they moved beyond small displacements
        (:attr:`holds`). Where every mode is predicted, the run's error is the prediction; for
        a step ``longer`` than the default one (a saving the prediction alone offers), and
        wherever modes were left out, what the start measured beyond the prediction is counted
        too, grown over the run (:meth:`run_error`), and the run confirmed only where that is
        within ``allowed``: ``AGREEMENT`` then decides only whether the start agrees, never how
        much of it is left uncounted (a curved shell under gravity, its start 1.47 times the
        prediction, measured 4.3 times it over the run at 1.8 times its default step).
        """
        if self.predictor is None or not self.holds:
            return math.nan
        expected = self.start_error(dt, over_s)
        if (measured > max(allowed, AGREEMENT * expected)
                or self.beyond(measured, dt, over_s, allowed)):
            return math.nan
        if self.predictor.complete and not longer:
            return self.predictor.error(dt)
        error = self.run_error(measured, dt, over_s)
        return error if error <= allowed else math.nan

    def beyond(self, measured: float, dt: float, over_s: float, allowed: float) -> bool:
        """
        Tell whether a start that measured ``measured`` moved beyond what the modes predict.

        More than ``NONLINEAR`` times the error predicted over the start (its first
        ``over_s``), and more than a tenth of what is ``allowed`` (below it, any start is
        smooth enough).
        """
        return measured > max(NONLINEAR * self.start_error(dt, over_s), 0.1 * allowed)

    @property
    def leaves_modes_out(self) -> bool:
        """Tell whether the prediction steps only the lowest modes (beyond the dense limit)."""
        return self.predictor is not None and not self.predictor.complete

    def start_growth(self, over_s: float, dt: float) -> float:
        """
        Return how much a start's error beyond the modes' prediction at ``dt`` grows over the run.

        Where every mode is predicted, as the prediction grows from the start (its first
        ``over_s``) to the run: an excess is the same modes' error, under-predicted. With modes
        left out, the start's grown as a drift of theirs (:func:`drift_growth`). Never below 1.
        """
        if self.leaves_modes_out:
            return drift_growth(self.predictor.horizon_s, over_s, self.predictor.slowest_decay)
        start = self.start_error(dt, over_s)
        return max(1.0, self.predictor.error(dt) / start) if start > 0.0 else 1.0

    def run_error(self, measured: float, dt: float, over_s: float) -> float:
        """
        Return the run's error at ``dt`` from what its first ``over_s`` measured.

        The modes' prediction over the run, and what the start measured beyond it grown over
        the run (:meth:`start_growth`); never below the prediction.
        """
        excess = max(0.0, measured - self.start_error(dt, over_s))
        return self.predictor.error(dt) + excess * self.start_growth(over_s, dt)

    def describe(self) -> str:
        """Say what the prediction steps: every mode, or the lowest the scene has ('' for none)."""
        if self.predictor is None or self.predictor.complete:
            return ''
        return (f'predicted from its {self.predictor.count} lowest modes (up to '
                f'{self.predictor.highest_hz:.3g} Hz, {QUASI_STATIC:g} times its fastest drive or '
                'more: the others follow it), what its start measured beyond them grown over the '
                'run')


def predicted_step(model: MassSpringModel, basis: ModalBasis, name: str, dt: float,
                   horizon_s: float, tolerance: float, longest_dt: float | None = None
                   ) -> StepPrediction:
    """
    Return the longest step predicted to keep a full run within ``tolerance``.

    From ``dt``'s prediction (the default step) and the error's order: shorter where ``dt`` is
    predicted beyond the tolerance (in ``MAX_PREDICTIONS`` at most), else the longer step the
    order gives up to ``longest_dt``, kept where its own prediction confirms it (each costs a
    run of every mode: a few, so that planning stays a small share of what it plans).
    """
    predictor = StepErrorPredictor(model, basis, name, horizon_s)
    step, error = dt, predictor.error(dt)
    for _ in range(MAX_PREDICTIONS - 1):
        if error <= tolerance:
            break
        step *= (SETTLE * (tolerance / error) ** (1.0 / ORDER) if math.isfinite(error)
                 else 0.5)
        error = predictor.error(step)
    if step == dt and longest_dt is not None and longest_dt > dt:
        longer = min(longest_dt, dt * SETTLE * (tolerance / error) ** (1.0 / ORDER)
                     if error > 0.0 else longest_dt)
        if longer > dt * (1.0 + LONGER_WORTH):
            longer_error = predictor.error(longer)
            if longer_error <= tolerance:
                step, error = longer, longer_error
    return StepPrediction(step, error, predictor)

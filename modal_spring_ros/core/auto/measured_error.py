"""
How a run's error is measured: the same instants, a relative L2 error, beyond the window.

Runs are compared on one grid of sample instants (:func:`on_samples` lands a run's step on
it), by the relative L2 error of the free-DOF displacement in the clamp's frame
(:func:`trajectory_error`), against a reference converged in its step
(:func:`converged_trajectory`). An error measured over a window is extrapolated to a longer
run by a drift model (:func:`horizon_error`; a transient's, decaying as the scene damps:
:func:`drift_growth`); a run already beyond what could be chosen is
abandoned part-way by an exact lower bound (:func:`error_at_least`).
"""
from __future__ import annotations

import math
from typing import Callable, NamedTuple

from modal_spring_ros.core.auto.work_model import work_per_second
from modal_spring_ros.core.simulations import DivergenceError, RunState, Simulation
import numpy as np
import scipy.special

#: Blocks of the window's second half the drift model is fitted to.
DRIFT_BLOCKS = 4
#: How often over its window a run that may be abandoned is checked.
GIVE_UP_CHECKS = 8
#: The promise's window, s, and how many tolerances a run may be off within any one of them.
PROMISE_WINDOW_S, WINDOW_ALLOWANCE = 0.25, 2.0


def on_samples(sim: Simulation, sample_s: float, longest_dt: float | None = None
               ) -> Simulation:
    """
    Return ``sim`` at the longest step that divides ``sample_s``, no longer than its own.

    (or than ``longest_dt`` when given); ``sim`` itself where its step already does.
    """
    step = sim.dt if longest_dt is None else longest_dt
    dt = sample_s / max(1, math.ceil(sample_s / step - 1e-9))
    return sim if abs(dt - sim.dt) <= 1e-9 * dt else sim.with_dt(dt)


def trajectory(sim: Simulation, sample_s: float, samples: int,
               give_up: Callable[[np.ndarray], bool] | None = None,
               ended: Callable[[RunState], None] | None = None) -> np.ndarray | None:
    """
    Return the displacement every ``sample_s`` from rest, or None where the run diverges.

    ``give_up(so_far)`` is asked every ``GIVE_UP_CHECKS``-th of the run with the samples so
    far; where it says yes the run stops there and those samples are returned (fewer than
    ``samples``: see :func:`error_at_least`). ``ended(state)`` is given the run's state after
    its last sample, where it took them all (a run can go on from there: a head start).
    """
    per = max(1, int(round(sample_s / sim.dt)))
    if abs(per * sim.dt - sample_s) > 1e-6 * sample_s:
        raise ValueError(f'samples every {sample_s:.6g} s do not fall on steps of '
                         f'{sim.dt:.6g} s')
    out = np.empty((samples, sim.model.n_free_dof))
    check = max(1, samples // GIVE_UP_CHECKS)
    sim.reset()
    try:
        for k in range(samples):
            sim.step(per)
            out[k] = sim.displacement()
            if give_up is not None and (k + 1) % check == 0 and k + 1 < samples:
                if np.isfinite(out[:k + 1]).all() and give_up(out[:k + 1]):
                    return out[:k + 1]
        if ended is not None and np.isfinite(out).all():
            ended(RunState.of(sim))
    except DivergenceError:
        return None
    finally:
        sim.reset()
    return out if np.isfinite(out).all() else None


class SteppedRun(NamedTuple):
    """A run stepped from rest over a whole window: its samples, and its state after them."""

    samples: np.ndarray | None       # None: it diverged
    end: RunState | None


def stepped_trajectory(sim: Simulation, sample_s: float, samples: int, stepped: dict,
                       give_up: Callable[[np.ndarray], bool] | None = None
                       ) -> np.ndarray | None:
    """
    Return :func:`trajectory`, stepped once for all who ask: kept in ``stepped``.

    ``stepped``: the runs of one set of settings (a pilot's full runs), each a
    :class:`SteppedRun` by step, sample interval and count, so that a second look at the same
    run steps nothing again and a run can go on from where one ended (a head start). A run
    given up part-way (``give_up``) is returned, not kept.
    """
    key = (sim.dt, sample_s, samples)
    if key not in stepped:
        ended: list[RunState] = []
        found = trajectory(sim, sample_s, samples, give_up, ended=ended.append)
        if found is not None and len(found) < samples:
            return found
        stepped[key] = SteppedRun(found, ended[0] if ended else None)
    return stepped[key].samples


def bounded_trajectory(sim: Simulation, sample_s: float, reference: np.ndarray,
                       ceiling: float = math.inf, stepped: dict | None = None
                       ) -> tuple[np.ndarray | None, float | None]:
    """
    Return :func:`trajectory` over ``reference``'s samples, and None, or abandoned part-way.

    Abandoned where its error is certain to exceed ``ceiling`` (:func:`error_at_least`): the
    samples stepped, and that bound. ``stepped``: kept there, or taken from it where it was
    (:func:`stepped_trajectory`).
    """
    give_up = ((lambda start: error_at_least(start, reference) > ceiling)
               if math.isfinite(ceiling) else None)
    run = (trajectory(sim, sample_s, len(reference), give_up) if stepped is None
           else stepped_trajectory(sim, sample_s, len(reference), stepped, give_up))
    if run is not None and len(run) < len(reference):
        return run, error_at_least(run, reference)
    return run, None


def error_at_least(start: np.ndarray, reference: np.ndarray) -> float:
    """
    Return a lower bound of a run's :func:`trajectory_error` from its first samples ``start``.

    The error still to come can only add to the numerator, while the denominator (the
    reference's whole motion) is known: the bound is exact, so a run it puts beyond what could
    be chosen is abandoned without stepping the rest of its window. A run's error over a
    horizon is never below its window's (:func:`horizon_error`), so it bounds that too.
    """
    norm = float(np.linalg.norm(reference))
    return float(np.linalg.norm(start - reference[:len(start)])) / norm if norm > 0 else 0.0


def trajectory_error(run: np.ndarray | None, reference: np.ndarray) -> float:
    """Relative L2 error of a trajectory against the reference (inf where it diverged)."""
    if run is None:
        return math.inf
    # squared sums without BLAS: its threads' wake-up cost 0.3-0.5 ms a norm on 2 cores, many
    # times the sum, and planning measures thousands
    difference, reference = np.ravel(run - reference), np.ravel(reference)
    norm = math.sqrt(float(np.einsum('i,i->', reference, reference)))
    error = math.sqrt(float(np.einsum('i,i->', difference, difference)))
    return error / norm if norm > 0 else 0.0


def worst_window(run: np.ndarray | None, reference: np.ndarray, sample_s: float) -> float:
    """
    Return the largest error of ``run`` over windows of about ``PROMISE_WINDOW_S`` (inf: diverged).

    The promise holds over the run within the tolerance and within ``WINDOW_ALLOWANCE`` times
    it in every such window: an error averaged over a run hides one that grows. The samples are
    split into windows of equal length, the nearest to ``PROMISE_WINDOW_S`` that fits the run
    (a last window of a few samples would judge a moment, not a window); samples further apart
    than a window (a long run's prediction) are each a window of their own.
    """
    if run is None:
        return math.inf
    return float(trajectory_windows(run, reference, sample_s).max())


def trajectory_windows(run: np.ndarray, reference: np.ndarray, sample_s: float) -> np.ndarray:
    """Return the error of each of :func:`worst_window`'s windows of ``run``, in order."""
    return window_errors(np.einsum('ij,ij->i', run - reference, run - reference),
                         np.einsum('ij,ij->i', reference, reference), sample_s)


def window_errors(difference: np.ndarray, motion: np.ndarray, sample_s: float) -> np.ndarray:
    """
    Return the error of each of :func:`worst_window`'s windows, in order (inf: diverged).

    From each sample's squared sums (of the difference, of the reference), for a caller that
    steps its runs sample by sample and keeps only those (a watched window). No sample: one
    window without error.
    """
    if len(motion) == 0:
        return np.zeros(1)
    count = min(len(motion), max(1, int(round(len(motion) * sample_s / PROMISE_WINDOW_S))))
    starts = [window[0] for window in np.array_split(np.arange(len(motion)), count)]
    difference = np.add.reduceat(np.asarray(difference, dtype=float), starts)
    motion = np.add.reduceat(np.asarray(motion, dtype=float), starts)
    ratios = np.divide(difference, motion, out=np.zeros_like(difference), where=motion > 0)
    return np.where(np.isfinite(difference), np.sqrt(ratios), math.inf)


def converged_trajectory(run_at: Callable[[float], Simulation], step: float, sample_s: float,
                         samples: int, accuracy: float, work_per_s: float = math.inf,
                         charge: Callable[[Simulation], None] | None = None,
                         stepped: dict | None = None) -> tuple[np.ndarray, float] | None:
    """
    Return a run's trajectory converged in its step, and the finer step it was computed at.

    ``run_at(dt)`` builds the run at a step no longer than ``dt`` (landing on the samples).
    Step doubling: a second-order scheme's error at ``h / 2`` is about a third of the
    difference between its runs at ``h`` and ``h / 2``; the step is halved from ``step`` until
    that is within ``accuracy`` (relative), and the Richardson extrapolation of the last two is
    returned. None when it diverges, or when the modelled work of the runs so far passes
    ``work_per_s`` (us per simulated second, summed over the runs). ``charge(sim)`` is told of
    each run before it is stepped (a planning budget counts it). ``stepped``: its runs kept
    there (:func:`stepped_trajectory`), a run kept from before neither stepped nor charged.
    """
    spent, coarse, stepped = 0.0, None, {} if stepped is None else stepped
    while True:
        sim = run_at(step)
        spent += work_per_second(sim)
        if spent > work_per_s:
            return None
        if charge is not None and (sim.dt, sample_s, samples) not in stepped:
            charge(sim)
        fine = stepped_trajectory(sim, sample_s, samples, stepped)
        if fine is None:
            return None
        if coarse is not None and trajectory_error(coarse, fine) / 3.0 <= accuracy:
            return (4.0 * fine - coarse) / 3.0, sim.dt
        coarse, step = fine, sim.dt / 2.0


def horizon_error(run: np.ndarray | None, reference: np.ndarray, sample_s: float,
                  horizon_s: float) -> float:
    """
    Return the relative L2 error of ``run`` over ``horizon_s``, measured or extrapolated.

    Within the window (``len(reference)`` samples every ``sample_s``) it is
    :func:`trajectory_error`. Beyond it, the error model of a stepped oscillation: the size of
    the error relative to the motion is a constant (truncation) plus a term growing linearly in
    time (phase drift), ``a + b t``. It is fitted to ``DRIFT_BLOCKS`` blocks of the window's
    second half (after the start's transient; ``b`` not below 0) and integrated over the rest of
    the horizon with the motion's mean square of the last block. Never less than the window's.
    """
    error = trajectory_error(run, reference)
    window_s = len(reference) * sample_s
    if run is None or not math.isfinite(error) or horizon_s <= window_s * (1.0 + 1e-9):
        return error
    squared = np.sum((run - reference) ** 2, axis=1)
    motion = np.sum(reference * reference, axis=1)
    blocks = [b for b in np.array_split(np.arange(len(reference) // 2, len(reference)),
                                        DRIFT_BLOCKS) if len(b) and motion[b].sum() > 0.0]
    if len(blocks) < 2:
        return error
    t = np.array([(b.mean() + 1.0) * sample_s for b in blocks])
    size = np.array([math.sqrt(squared[b].sum() / motion[b].sum()) for b in blocks])
    growth, at_zero = np.polyfit(t, size, 1)
    growth = max(float(growth), 0.0)
    power = float(motion[blocks[-1]].mean()) / sample_s          # per second of the motion

    def integral(x: float) -> float:                             # of (a + b t)^2
        return ((at_zero + growth * x) ** 3 / (3.0 * growth) if growth > 0.0
                else at_zero * at_zero * x)

    beyond = power * (horizon_s - window_s)
    errors = float(squared.sum()) + power * (integral(horizon_s) - integral(window_s))
    return max(error, math.sqrt(errors / (float(motion.sum()) + beyond)))


def drift_growth(horizon_s: float, start_s: float, decay: float) -> float:
    """
    Return how much more a drift's relative L2 error is over ``horizon_s`` than over ``start_s``.

    A transient of decay rate ``decay`` (1/s) stepped with a period error drifts in phase in
    proportion to time: its error at ``t`` is ``t exp(-decay t)`` (times its amplitude and the
    frequency's error), and over a run its RMS, ``sqrt(int_0^T t^2 exp(-2 decay t) dt / T)``. The
    ratio of the two runs' RMS: ``horizon_s / start_s`` undamped, less where it decays (the
    reference's own norm taken as steady), and never below 1.
    """
    def rms(t: float) -> float:
        a = 2.0 * decay * t
        if a < 1e-6:
            return t / math.sqrt(3.0)
        # int_0^t tau^2 exp(-a tau / t) dtau = 2 t^3 P(3, a) / a^3 (the regularised gamma)
        return t * math.sqrt(2.0 * scipy.special.gammainc(3.0, a) / a ** 3)
    return max(1.0, rms(horizon_s) / rms(start_s)) if start_s > 0.0 else math.inf

"""
A run the pilot chose as the full run, watched by its twin alone, and which runs can be watched.

The full run's step was measured over its start; what no start shows is a motion that turns
chaotic later (:mod:`~modal_spring_ros.core.auto.watch.amplification`). Such a run is watched by
a twin moved by a hair (:func:`twin_reference`), stepped beside the run itself where its caller
steps it one step at a time, over a window that costs at most ``TWIN_SHARE`` of a run of given
length (:func:`within_share`): the twin's quarter second in runs of 2.5 s and more, a tenth of
the run in shorter ones down to ``SHORTEST_TWIN_S``. A full run a plan fell back to is watched
the same way (:func:`twin_watched`).
"""
from __future__ import annotations

import dataclasses

from modal_spring_ros.core.auto.watch.amplification import (SAMPLES as TWIN_SAMPLES,
                                                            WINDOW_S as TWIN_WINDOW_S)
from modal_spring_ros.core.auto.watch.windows import WatchReference
from modal_spring_ros.core.auto.work_model import work_per_second
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.motion.anchor_motion import AnchorMotion
from modal_spring_ros.core.simulations import Simulation

#: A full run the pilot chose is watched by its twin alone (over ``TWIN_WINDOW_S`` on
#: ``TWIN_SAMPLES`` samples, stepped beside the run) in a run where it costs at most this share
#: of it (what planning may spend: ``PLANNING_SHARE`` in
#: :mod:`~modal_spring_ros.core.auto.budget`): runs of 2.5 s and more, and in shorter ones over
#: that share of the run, down to ``SHORTEST_TWIN_S``.
TWIN_SHARE = 0.1
#: The shortest window a twin is stepped over (runs of 1 s and more are watched): converging
#: motions (the full runs of 95 random scenes, from six states each) measured at most 1.3
#: e-folds per second over windows of 0.1 s (0.6 over 0.25 s), below ``AMPLIFYING_PER_S``.
SHORTEST_TWIN_S = 0.1


def watchable(model: MassSpringModel) -> bool:
    """Tell whether a run of ``model`` can be watched (its clamp moves as a function of time)."""
    return isinstance(model.motion, AnchorMotion)


def within_share(reference: WatchReference, run_s: float) -> WatchReference | None:
    """
    Return the twin-only ``reference`` over a window within ``TWIN_SHARE`` of a run of ``run_s``.

    Its window as it is where it fits; shortened to that share (its samples closer, as many)
    where the run is shorter, down to ``SHORTEST_TWIN_S``; None below it.
    """
    share = TWIN_SHARE * run_s
    if reference.window_s <= share * (1.0 + 1e-9):
        return reference
    if share < SHORTEST_TWIN_S * (1.0 - 1e-9):
        return None
    return dataclasses.replace(reference, sample_s=share / reference.samples)


def twin_reference(sim: Simulation, tolerance: float) -> 'WatchReference':
    """
    Return what the full run ``sim`` the pilot chose is watched against: its twin alone.

    Its step's error was measured over its start, and the step the pilot found is what a
    fallback would take: the watch measures only whether the motion amplifies its differences.
    """
    work = work_per_second(sim)
    return WatchReference(None, None, {}, '', TWIN_WINDOW_S / TWIN_SAMPLES, TWIN_SAMPLES, 1.0,
                          tolerance, work, 2.0 * work)


def twin_watched(fallback: Simulation, tolerance: float) -> bool:
    """
    Give the full run a plan fell back to its twin to be watched by; tell whether it has one.

    As a full run the pilot chose (:func:`twin_reference`): its step was measured over the
    pilot's window only, and a motion gone chaotic holds no tolerance, the fallback's included.
    A run with a reference of its own keeps it.
    """
    if fallback.method != 'full' or not watchable(fallback.model):
        return False
    if fallback.watch_reference is None:
        fallback.watch_reference = twin_reference(fallback, tolerance)
    return True

"""
The shadow runs of a watched window, stepped from the run's state sample by sample.

The plan's copy, the reference (where the watch has one) and the plan's twin moved by a hair:
stepped in slices against a wall-clock deadline, so that a caller that streams frames steps them
in its idle time (:mod:`~modal_spring_ros.core.auto.watch.run_watch`).
"""
from __future__ import annotations

import math
import time

from modal_spring_ros.core.auto.measured_error import window_errors
from modal_spring_ros.core.auto.watch.amplification import (Growth, perturbed,
                                                            stepped_displacement,
                                                            twin_samples)
from modal_spring_ros.core.auto.watch.windows import WatchedWindow, WatchReference
from modal_spring_ros.core.simulations import DivergenceError, RunState, Simulation
import numpy as np


class Shadows:
    """
    The plan's copy, the reference and the plan's twin, from one state, stepped sample by sample.

    ``runs``: the plan's copy, the reference (where the watch has one) and the twin, built once
    per watch and taken over to each window's state (the twin's perturbed by a hair; stepped
    over the window's first ``TWIN_WINDOW_S`` only). ``cause``: why the window started before
    it was due (empty: it was due).
    """

    def __init__(self, plan: Simulation, runs: list[Simulation], reference: WatchReference,
                 cause: str = ''):
        state = RunState.of(plan)
        self.start_s = state.time
        self.reference, self.cause = reference, cause
        self._runs = runs
        for run in runs[:-1]:
            run.take_over(state)
        runs[-1].take_over(perturbed(state))
        self._per = [max(1, int(round(reference.sample_s / run.dt))) for run in self._runs]
        self._growth = Growth(self._per[0] * runs[0].dt)
        self._twin_samples = twin_samples(reference.sample_s, reference.samples)
        self._done = 0
        self._differences: list[float] = []    # each sample's squared sums
        self._motions: list[float] = []
        self.result: WatchedWindow | None = None

    def advance(self, deadline: float) -> bool:
        """Step whole samples until the window is done (True) or past ``deadline`` (monotonic)."""
        ref = self.reference
        while self.result is None:
            try:
                plan = self._sample(0)
            except DivergenceError:
                return self._finish(math.inf)
            if ref.reference is not None:
                try:
                    truth = self._sample(1)
                except DivergenceError:
                    return self._finish(math.nan)
                self._differences.append(float(np.sum((plan - truth) ** 2)))
                self._motions.append(float(truth @ truth))
            if self._done < self._twin_samples and not self._growth.diverged:
                try:
                    self._growth.add(plan, self._sample(len(self._runs) - 1))
                except DivergenceError:
                    self._growth.diverged = True
            self._done += 1
            if self._done >= ref.samples:
                return self._finish(*self._errors())
            if time.monotonic() >= deadline:
                return False
        return True

    def _sample(self, which: int) -> np.ndarray:
        return stepped_displacement(self._runs[which], self._per[which])

    def _errors(self) -> tuple[float, float, float]:
        """
        Return the window's error, its worst quarter second's and where it is heading (nan: none).

        Heading: the quarter-second errors of the window's second half, on the straight line
        fitted to them, one more window on (never below the last one's).
        """
        ref = self.reference
        if ref.reference is None:
            return math.nan, math.nan, math.nan
        difference, motion = np.array(self._differences), np.array(self._motions)
        error = math.sqrt(difference.sum() / motion.sum()) if motion.sum() > 0.0 else 0.0
        quarters = window_errors(difference, motion, ref.sample_s)
        heading = quarters[-1]
        late = quarters[len(quarters) // 2:]
        if late.size >= 2 and np.all(np.isfinite(late)):
            span = ref.window_s / quarters.size          # each quarter's length, s
            slope = np.polyfit(np.arange(late.size) * span, late, 1)[0]
            heading = max(heading, heading + slope * ref.window_s)
        return error * ref.shared, quarters.max() * ref.shared, heading * ref.shared

    def _finish(self, error: float, worst: float | None = None, heading: float | None = None
                ) -> bool:
        ref = self.reference
        self.result = WatchedWindow(self.start_s, ref.window_s, error, ref.tolerance,
                                    ref.against, self._growth.rate(), self.cause,
                                    error if worst is None else float(worst),
                                    error if heading is None else float(heading))
        return True

"""
The shadow runs of a watched window, stepped from the run's state sample by sample.

The plan's copy, the reference (where the watch has one) and the plan's twin moved by a hair:
stepped in slices against a wall-clock deadline, so that a caller that streams frames steps them
in its idle time (:mod:`~modal_spring_ros.core.auto.watch.run_watch`).
"""
from __future__ import annotations

import math
import time

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
    over the window's first ``TWIN_WINDOW_S`` only).
    """

    def __init__(self, plan: Simulation, runs: list[Simulation], reference: WatchReference):
        state = RunState.of(plan)
        self.start_s = state.time
        self.reference = reference
        self._runs = runs
        for run in runs[:-1]:
            run.take_over(state)
        runs[-1].take_over(perturbed(state))
        self._per = [max(1, int(round(reference.sample_s / run.dt))) for run in self._runs]
        self._growth = Growth(self._per[0] * runs[0].dt)
        self._twin_samples = twin_samples(reference.sample_s, reference.samples)
        self._done = 0
        self._difference = self._motion = 0.0
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
                self._difference += float(np.sum((plan - truth) ** 2))
                self._motion += float(truth @ truth)
            if self._done < self._twin_samples and not self._growth.diverged:
                try:
                    self._growth.add(plan, self._sample(len(self._runs) - 1))
                except DivergenceError:
                    self._growth.diverged = True
            self._done += 1
            if self._done >= ref.samples:
                error = (math.nan if ref.reference is None
                         else math.sqrt(self._difference / self._motion) * ref.shared
                         if self._motion > 0.0 else 0.0)
                return self._finish(error)
            if time.monotonic() >= deadline:
                return False
        return True

    def _sample(self, which: int) -> np.ndarray:
        return stepped_displacement(self._runs[which], self._per[which])

    def _finish(self, error: float) -> bool:
        ref = self.reference
        self.result = WatchedWindow(self.start_s, ref.window_s, error, ref.tolerance,
                                    ref.against, self._growth.rate())
        return True

"""Operators of stepped sets built ahead of a band switch, kept until the switch takes them."""
from __future__ import annotations

import threading
from typing import Callable

from modal_spring_ros.core.simulations.stepped_set import SteppedSet
import numpy as np

#: Stepped-mode sets kept prepared ahead (a switch needs two: the modes stepped during its
#: transition and after it); the oldest goes first.
PREPARED_SETS_KEPT = 4


class PreparedSets:
    """
    Stepped sets built by ``build(modes, settled)`` from any thread, each taken once.

    A set is keyed by the basis size it was built for (a basis that grew since builds anew), its
    modes, and whether it is settled (no coordinate fading, so its springs may be sampled).
    """

    def __init__(self, build: Callable[[np.ndarray, bool], SteppedSet],
                 kept: int = PREPARED_SETS_KEPT):
        self._build = build
        self._kept = kept
        self._sets: dict[tuple[int, bytes, bool], SteppedSet] = {}
        self._lock = threading.Lock()

    def prepare(self, basis_count: int, modes: np.ndarray, settled: bool) -> None:
        """Build the set of ``modes`` now (the slow part of a switch), unless it is ready."""
        key = (basis_count, modes.tobytes(), settled)
        with self._lock:
            if key in self._sets:
                return
        built = self._build(modes, settled)
        with self._lock:  # the stepping thread may take from it meanwhile
            self._sets[key] = built
            while len(self._sets) > self._kept:  # a switch superseded before use
                self._sets.pop(next(iter(self._sets)))

    def take(self, basis_count: int, modes: np.ndarray, settled: bool) -> SteppedSet:
        """Return the prepared set of ``modes`` (used once), else build it now."""
        with self._lock:
            built = self._sets.pop((basis_count, modes.tobytes(), settled), None)
        return built if built is not None else self._build(modes, settled)

"""Operators of stepped sets built ahead of a band switch, kept until the switch takes them."""
from __future__ import annotations

import threading
from typing import Callable, Hashable

from modal_spring_ros.core.simulations.stepped_set import SteppedSet
import numpy as np

#: Stepped-mode sets kept prepared ahead (a switch needs two: the modes stepped during its
#: transition and after it); the oldest goes first.
PREPARED_SETS_KEPT = 4


class PreparedSets:
    """
    Stepped sets built by ``build(modes, settled, variant)`` from any thread, each taken once.

    A set is keyed by the basis size it was built for (a basis that grew since builds anew), its
    modes, whether it is settled (no coordinate fading, so its springs may be sampled), and a
    ``variant`` of what else it is built from (the band's damping ranges).
    """

    def __init__(self, build: Callable[[np.ndarray, bool, Hashable], SteppedSet],
                 kept: int = PREPARED_SETS_KEPT):
        self._build = build
        self._kept = kept
        self._sets: dict[tuple[int, bytes, bool, Hashable], SteppedSet] = {}
        self._lock = threading.Lock()

    def prepare(self, basis_count: int, modes: np.ndarray, settled: bool,
                variant: Hashable = ()) -> None:
        """Build the set of ``modes`` now (the slow part of a switch), unless it is ready."""
        key = (basis_count, modes.tobytes(), settled, variant)
        with self._lock:
            if key in self._sets:
                return
        built = self._build(modes, settled, variant)
        with self._lock:  # the stepping thread may take from it meanwhile
            self._sets[key] = built
            while len(self._sets) > self._kept:  # a switch superseded before use
                self._sets.pop(next(iter(self._sets)))

    def take(self, basis_count: int, modes: np.ndarray, settled: bool,
             variant: Hashable = ()) -> SteppedSet:
        """Return the prepared set of ``modes`` (used once), else build it now."""
        with self._lock:
            built = self._sets.pop((basis_count, modes.tobytes(), settled, variant), None)
        return built if built is not None else self._build(modes, settled, variant)

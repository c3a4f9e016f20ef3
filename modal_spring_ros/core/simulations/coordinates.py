"""
The coordinates a modal run steps.

Which ones (an :class:`ActiveSet`, with each one's fade progress) and what they are (an
:class:`AddedCoordinateBank` for what bands add to their rest modes).

A coordinate is identified by an id: a rest mode by its index, an added coordinate by an id
from :data:`ADDED_ID` up.
"""
from __future__ import annotations

import dataclasses
import threading

from modal_spring_ros.core.bases.basis import ModalBasis, Progress
from modal_spring_ros.core.bases.derivatives import added_coordinates, AddedCoordinates
import numpy as np

#: The bases a modal run can step: the paper's rest modes, or rest modes and their derivatives.
BASES = ('rest', 'derivatives')
#: Ids of added coordinates start here (rest modes are ids 0, 1, ...).
ADDED_ID = 1 << 40
#: guards the banks of every basis (:func:`shared_bank`)
_BANKS_LOCK = threading.Lock()


class AddedCoordinateBank:
    """
    The coordinates bands add, by band, with their ids.

    Shared by the copies of a run (:meth:`ModalSimulation.with_dt`) so that a band's derivatives
    are computed once.
    """

    def __init__(self, basis: ModalBasis, directions: int, progress: Progress | None = None):
        self.basis = basis
        self.directions = int(directions)
        self.progress = progress
        self._blocks: dict[bytes, tuple[np.ndarray, AddedCoordinates]] = {}
        self._vectors: dict[int, np.ndarray] = {}
        self._omega: dict[int, float] = {}
        self._loads: dict[int, np.ndarray] = {}
        self._next = ADDED_ID
        self._lock = threading.Lock()

    def for_band(self, keep: np.ndarray) -> tuple[np.ndarray, AddedCoordinates]:
        """
        Return the ids and coordinates the band keeping rest modes ``keep`` adds.

        The ids and coordinates the band keeping rest modes ``keep`` adds (computed on its first
        use, from any thread). The computation holds no lock: the simulation thread reads the bank
        meanwhile; of two threads computing the same band, the first to finish is kept.
        """
        found = self.lookup(keep)
        if found is not None:
            return found
        added = added_coordinates(self.basis, keep, self.directions, self.progress)
        key = keep.tobytes()
        with self._lock:
            if key in self._blocks:
                return self._blocks[key]
            ids = np.arange(self._next, self._next + added.count, dtype=np.int64)
            self._next += added.count
            for k, i in enumerate(ids.tolist()):
                self._vectors[i] = added.vectors[:, k]
                self._omega[i] = float(added.omega[k])
                self._loads[i] = added.loads
            self._blocks[key] = (ids, added)
            return ids, added

    def lookup(self, keep: np.ndarray) -> tuple[np.ndarray, AddedCoordinates] | None:
        """Return what the band keeping ``keep`` adds, if it was computed (never computes)."""
        return self._blocks.get(keep.tobytes())

    def columns(self, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Shapes (n_free_dof, len(ids)) and ``omega`` of coordinates ``ids`` (rest or added)."""
        rest = ids < ADDED_ID
        phi = np.empty((self.basis.n_dof, ids.size))
        omega = np.empty(ids.size)
        phi[:, rest] = self.basis.vectors[:, ids[rest]]
        omega[rest] = self.basis.omega[ids[rest]]
        for k in np.flatnonzero(~rest):
            phi[:, k] = self._vectors[int(ids[k])]
            omega[k] = self._omega[int(ids[k])]
        return phi, omega

    def omega(self, ids: np.ndarray) -> np.ndarray:
        """``omega`` of coordinates ``ids`` (rest or added), without their shapes."""
        rest = ids < ADDED_ID
        omega = np.empty(ids.size)
        omega[rest] = self.basis.omega[ids[rest]]
        omega[~rest] = [self._omega[int(i)] for i in ids[~rest]]
        return omega

    def load_mask(self, ids: np.ndarray) -> np.ndarray:
        """
        Return which loads act on each coordinate, as (len(ids), 4) booleans.

        The loads are gravity and the base's x, y, z excitation (every load on a rest mode; the
        band's loads on an added coordinate).
        """
        mask = np.ones((ids.size, 4), dtype=bool)
        for k in np.flatnonzero(ids >= ADDED_ID):
            mask[k] = self._loads[int(ids[k])]
        return mask


@dataclasses.dataclass(frozen=True)
class ActiveSet:
    """
    The modes stepped.

    Which of them are in the band, and each one's fade progress (1 = fully in, 0 = out).
    """

    modes: np.ndarray
    target: np.ndarray
    progress: np.ndarray

    @classmethod
    def settled(cls, keep: np.ndarray) -> 'ActiveSet':
        keep = np.asarray(keep, dtype=np.int64)
        return cls(keep, np.ones(keep.size, dtype=bool), np.ones(keep.size))

    @property
    def fading(self) -> bool:
        return bool(np.any(self.progress < 1.0) or not np.all(self.target))

    @property
    def kept(self) -> np.ndarray:
        return self.modes[self.target]

    def switched(self, keep: np.ndarray, instant: bool) -> 'ActiveSet':
        """
        Return the active set once ``keep`` is the band.

        Modes new to the set fade in from 0, modes in both keep their progress, leaving ones fade
        out.
        """
        modes = self.next_modes(keep, instant)
        target = np.isin(modes, keep)
        was = np.isin(modes, self.modes)
        progress = np.zeros(modes.size)
        progress[was] = self.progress[np.searchsorted(self.modes, modes[was])]
        if instant or not self.modes.size:
            progress[target] = 1.0
        return ActiveSet(modes, target, progress)

    def next_modes(self, keep: np.ndarray, instant: bool) -> np.ndarray:
        """Modes stepped once ``keep`` is the band: ``keep`` plus the modes still fading out."""
        leaving = self.modes[~np.isin(self.modes, keep) & (self.progress > 0.0)]
        return np.union1d(keep, leaving[:0] if instant else leaving).astype(np.int64)


EMPTY_SET = ActiveSet(np.empty(0, dtype=np.int64), np.empty(0, dtype=bool), np.empty(0))


def shared_bank(basis: ModalBasis, directions: int) -> AddedCoordinateBank:
    """
    Return the bank of ``basis``'s added coordinates for ``directions``, one per pair.

    Every run built on a basis (a parameter change rebuilding it, a node's first run and the
    one it prepares next) shares it: a band's derivatives are computed once, and keep their ids.
    """
    with _BANKS_LOCK:
        bank = basis.banks.get(int(directions))
        if bank is None:
            bank = basis.banks[int(directions)] = AddedCoordinateBank(basis, directions,
                                                                      basis.progress)
        return bank

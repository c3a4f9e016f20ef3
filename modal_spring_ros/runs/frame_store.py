"""
The frames a run keeps: in memory where they are few, in a file beside the output where not.

A run written to ``.npz`` keeps every frame it makes until it is written. Kept as a list of
arrays and stacked at the end, a 20 s run of a 484-particle solid at its 42 us step (473,601
frames, 5.5 GB of positions) held three copies at once: 16 GB. A :class:`FrameStore` holds one:
an array of the frames the run can make, allocated once, in memory up to ``IN_MEMORY_BYTES``
and beyond that mapped from an unnamed file in the folder the run is written to (the kernel
writes its pages out as they fill, so the run's memory stays what the simulation takes; the
file goes with the process, whatever ends it). :func:`check_room` says whether a disk holds
that, before the run starts.
"""
from __future__ import annotations

import math
import os
from pathlib import Path
import shutil
import tempfile

from modal_spring_ros.core.memory_estimate import gib
import numpy as np

#: frames above this many bytes are kept in a file, not in memory
IN_MEMORY_BYTES = 256 * 1024 * 1024
#: bytes of one particle's position in a frame (three float64)
POSITION_BYTES = 3 * 8


def frame_count(duration: float, dt: float, frame_every: int) -> int:
    """Return how many frames a run of ``duration`` s at ``dt`` keeps (t = 0 included)."""
    steps = int(round(duration / dt))
    return steps // max(int(frame_every), 1) + 1


def frames_bytes(frames: int, n_particles: int) -> int:
    """Return the bytes ``frames`` frames of ``n_particles`` particles take (and their times)."""
    return frames * (n_particles * POSITION_BYTES + 8)


def check_room(path: str | Path, frames: int, n_particles: int, label: str = '') -> None:
    """
    Check that the disk under ``path`` holds a run of ``frames`` frames written there.

    The frames are kept in a file beside ``path`` while the run goes on where they are too many
    for memory (:class:`FrameStore`), and written to ``path`` at its end: twice their size then.
    A disk without that room is a ``ValueError`` (starting with ``label``, else ``path``) that
    names the ``--frame-every`` that would fit.
    """
    size = frames_bytes(frames, n_particles)
    need = 2 * size if size > IN_MEMORY_BYTES else size
    folder = Path(path).resolve().parent
    try:
        free = shutil.disk_usage(folder).free
    except OSError:                   # not a folder on a disk (a device): writing will say
        return
    if need > free:
        fits = math.ceil(need / max(free, 1) * 1.05)
        raise ValueError(f'{label or path}: the run keeps {frames:,} frames of {n_particles:,} '
                         f'particles ({gib(size)}, {gib(need)} on disk while it is written), '
                         f'and {folder} has {gib(free)} free: keep fewer frames '
                         f'(--frame-every {fits} or more) or write elsewhere')


class FrameStore:
    """
    Frames of ``n_particles`` positions and their times, appended in order.

    ``capacity``: the frames expected (more are taken: the store grows by half again).
    ``directory``: where a store too large for memory keeps its file (None: the system's
    temporary folder); ``in_memory_bytes``: the most kept in memory (None: ``IN_MEMORY_BYTES``).
    """

    def __init__(self, capacity: int, n_particles: int, directory: str | Path | None = None,
                 in_memory_bytes: int | None = None):
        self.n_particles = int(n_particles)
        self.directory = None if directory is None else os.fspath(directory)
        self.in_memory_bytes = int(IN_MEMORY_BYTES if in_memory_bytes is None
                                   else in_memory_bytes)
        self.count = 0
        self._positions, self._times = self._allocate(max(int(capacity), 1))

    @property
    def on_disk(self) -> bool:
        """Tell whether the frames are kept in a file."""
        return isinstance(self._positions, np.memmap)

    def _allocate(self, capacity: int) -> tuple[np.ndarray, np.ndarray]:
        shape = (capacity, self.n_particles, 3)
        if frames_bytes(capacity, self.n_particles) <= self.in_memory_bytes:
            return np.empty(shape), np.empty(capacity)
        # unnamed where the system allows (O_TMPFILE): nothing is left behind, even on a kill
        with tempfile.TemporaryFile(dir=self.directory, prefix='.frames-') as fh:
            positions = np.memmap(fh, dtype=np.float64, mode='w+', shape=shape)
        return positions, np.empty(capacity)                # the map outlives the file object

    def append(self, t: float, positions: np.ndarray) -> None:
        """Keep one frame: ``positions`` (n, 3) at time ``t``."""
        if self.count == self._times.size:
            grown = self._allocate(self._times.size + max(self._times.size // 2, 1))
            grown[0][:self.count] = self._positions[:self.count]
            grown[1][:self.count] = self._times[:self.count]
            self._positions, self._times = grown
        self._positions[self.count] = positions
        self._times[self.count] = t
        self.count += 1

    def clear(self) -> None:
        """Forget the frames kept (the storage stays)."""
        self.count = 0

    @property
    def times(self) -> np.ndarray:
        """Return the frames' times, s (a view)."""
        return self._times[:self.count]

    @property
    def positions(self) -> np.ndarray:
        """Return the frames' positions, (frames, n, 3) (a view: in the file if there is one)."""
        return self._positions[:self.count]

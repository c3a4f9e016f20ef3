"""
What a comparison of two runs may hold in memory, judged before a run is read whole.

A run's positions are ``(frames, particles, 3)`` float64: a 10k-particle sheet written every
step over 10 s is 12 GB. :func:`~modal_spring_ros.runs.comparison.compare` holds about
``WORKING_COPIES`` arrays that size at once (both runs, the frames they share, their
difference, a run's deformation and its windowed spectrum), so a run whose positions take more
than that share of the memory left (:func:`positions_budget`) is refused, said why, before any
of it is read. An ``.npz`` run's size is read from its array's own header
(:func:`npz_positions`), which is input too: a header that declares more than its entry holds
is a damaged file, named as such, never allocated.
"""
from __future__ import annotations

import math
from pathlib import Path

from modal_spring_ros.scenes.fields.limits import available_memory
from modal_spring_ros.scenes.files.npz_headers import declared_arrays, DeclaredArray

#: Arrays the size of one run's positions a comparison holds at once, at most (about).
WORKING_COPIES = 12


class RunTooLarge(ValueError):
    """A run whose positions a comparison cannot hold in the memory left."""


def positions_budget() -> int:
    """Return the bytes one run's positions may take for a comparison to fit in memory."""
    return available_memory() // WORKING_COPIES


def check_fits(nbytes: int, what: str, frames: int, particles: int, budget: int) -> None:
    """
    Raise :class:`RunTooLarge` naming ``what`` where ``nbytes`` of positions exceed ``budget``.

    ``frames`` and ``particles``: what the run holds (said in the message).
    """
    if nbytes > budget:
        keep = math.ceil(nbytes / max(budget, 1))
        raise RunTooLarge(
            f'{what}: its positions take {nbytes / 1e9:.3g} GB ({frames:,} frames of '
            f'{particles:,} particles), more than a comparison can hold beside the other run '
            f'in the {budget * WORKING_COPIES / 1e9:.3g} GB free (about {WORKING_COPIES} arrays '
            f'that size): record it keeping fewer frames (--frame-every {keep} or more), or '
            'shorter')


def npz_positions(path: Path) -> DeclaredArray:
    """
    Return what an ``.npz`` run's ``positions`` declares, reading headers only.

    :raises ValueError: no ``positions`` array, or an entry that is not an ``.npy`` array or
        declares more than it holds (:func:`~modal_spring_ros.scenes.files.npz_headers.
        declared_arrays`); ``zipfile.BadZipFile``: not a zip archive.
    """
    declared = declared_arrays(path)
    if 'positions' not in declared:
        raise ValueError("no array 'positions'")
    return declared['positions']

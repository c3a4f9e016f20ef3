"""
Each stepped coordinate's gain (:mod:`~modal_spring_ros.core.filter_response`), faded on change.

A modal run's coordinates take part with two gains each: the *output* gain scales what the
coordinate adds to the streamed positions (the motion underneath stays as simulated, as an
equaliser colours a recording), the *load* gain scales the loads that drive it from outside
(gravity, inertial and applied loads; never the springs' own force, so its frequency stays;
the motion itself changes). A band's
``acts_on`` says which of the two its gains are; the other stays 1.

Rest modes take the band's gain at their frequency. Added coordinates (the ``derivatives``
basis: the kept modes' second-order response and the static response to the loads) have no
frequency of their own and take part as computed (gain 1): a gain colours the modes' linear
vibration, not the large-deformation correction that goes with it.

A change of gains while running fades from the gains in effect to the new ones along the same
raised cosine as a band change, over the band's transition time, so positions never jump.
"""
from __future__ import annotations

from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.filter_response import damping_ratios
from modal_spring_ros.core.simulations.coordinates import ADDED_ID
import numpy as np


def coordinate_gains(band: FilterBand, ids: np.ndarray,
                     frequencies_hz: np.ndarray) -> np.ndarray:
    """
    Return the (2, len(ids)) output and load gains of coordinates ``ids``.

    ``frequencies_hz`` are the rest modes' (by index). An unshaped band (ideal edges, no gain
    terms) gives every coordinate 1 (leaving modes fade by the band change's envelope alone).
    """
    gains = np.ones((2, ids.size))
    if not (band.order or band.gains):
        return gains
    rest = ids < ADDED_ID
    gains[0 if band.acts_on == 'output' else 1, rest] = band.gain(frequencies_hz[ids[rest]])
    return gains


def coordinate_damping(ranges: tuple[str, ...], ids: np.ndarray,
                       frequencies_hz: np.ndarray) -> np.ndarray:
    """
    Return the damping ratio a band's damping ``ranges`` give each of ``ids``.

    NaN: the scene's damping (every added coordinate keeps it).
    """
    ratios = np.full(ids.size, np.nan)
    if ranges:
        rest = ids < ADDED_ID
        ratios[rest] = damping_ratios(ranges, frequencies_hz[ids[rest]])
    return ratios


class GainFade:
    """The gains in effect: ``start`` faded to ``end`` as ``progress`` goes from 0 to 1."""

    def __init__(self, gains: np.ndarray):
        self.start = self.end = self.now = gains
        self.progress = 1.0
        self._update_flags()

    def _update_flags(self) -> None:
        #: the output gains are all 1 (positions need no scaling), the load gains likewise
        self.unit_output = bool(np.all(self.now[0] == 1.0))
        self.unit_load = bool(np.all(self.now[1] == 1.0))

    @property
    def fading(self) -> bool:
        return self.progress < 1.0

    def retarget(self, old_ids: np.ndarray, new_ids: np.ndarray, end: np.ndarray,
                 instant: bool) -> None:
        """
        Fade from the gains in effect to ``end`` (coordinates ``new_ids``).

        Coordinates new to the set start at their new gains (they start from rest).
        """
        start = end.copy()
        kept = np.isin(new_ids, old_ids)
        if kept.any() and old_ids.size == self.now.shape[1]:
            start[:, kept] = self.now[:, np.searchsorted(old_ids, new_ids[kept])]
        self.start, self.end = start, end
        self.progress = 1.0 if instant or np.array_equal(start, end) else 0.0
        self.now = end if self.progress >= 1.0 else start
        self._update_flags()

    def advance(self, share: float) -> None:
        """Move the fade on by ``share`` of the transition."""
        self.progress = min(1.0, self.progress + share)
        w = 0.5 - 0.5 * np.cos(np.pi * self.progress)
        self.now = self.end if self.progress >= 1.0 else self.start + w * (self.end - self.start)
        self._update_flags()

"""
The filter: which vibration modes take part, by frequency (Hz) or by mode index.

Band edges are inclusive and always name the pass band's (or, for ``bandstop``, the stop band's)
edges:

==========  ==========================================  ==========================
type        keeps modes with                            edges used
==========  ==========================================  ==========================
allpass     every mode                                  none
lowpass     f <= high                                   high
highpass    f >= low                                    low
bandpass    low <= f <= high                            low, high
bandstop    f < low or f > high                         low, high
==========  ==========================================  ==========================

With ``by="index"`` the same rules apply to zero-based mode numbers (sorted by frequency), which
is how the paper counts: its fig. 10b is ``lowpass`` with ``high = 14`` (modes 0..14 of 180), its
fig. 10d ``bandpass`` with ``low = 2, high = 48``.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Mapping

import numpy as np

FILTER_TYPES = ('allpass', 'lowpass', 'highpass', 'bandpass', 'bandstop')
UNITS = ('hz', 'index')


class BandError(ValueError):
    """An impossible filter band; the message names the field and the rule."""


@dataclasses.dataclass(frozen=True)
class FilterBand:
    kind: str = 'allpass'
    low: float = 0.0
    high: float = math.inf
    by: str = 'hz'

    @property
    def uses_low(self) -> bool:
        return self.kind in ('highpass', 'bandpass', 'bandstop')

    @property
    def uses_high(self) -> bool:
        return self.kind in ('lowpass', 'bandpass', 'bandstop')

    @property
    def bounded_above(self) -> bool:
        """Keep no mode above ``high`` (so only modes up to it must be computed)."""
        return self.kind in ('lowpass', 'bandpass')

    def edge_fields(self) -> tuple[str, str]:
        """Return what the two edges are called: ``low_hz, high_hz`` or ``low_mode, high_mode``."""
        if self.by == 'index':
            return 'low_mode', 'high_mode'
        return 'low_hz', 'high_hz'

    def validate(self, names: Mapping[str, str] | None = None) -> 'FilterBand':
        """
        Check the band on its own; returns self.

        ``names`` map ``type``, ``by`` and the edges (:meth:`edge_fields`) to what the user
        typed, so that an error names it (``filter.low_hz`` in the node, ``--low-hz`` on the
        command line); the field names by default.
        """
        names = names or {}
        low_name, high_name = (names.get(field, field) for field in self.edge_fields())
        if self.kind not in FILTER_TYPES:
            raise BandError(f"{names.get('type', 'filter type')} '{self.kind}' is not one of "
                            f"{', '.join(FILTER_TYPES)}")
        if self.by not in UNITS:
            raise BandError(f"{names.get('by', 'band units')} '{self.by}' must be 'hz' or "
                            "'index'")
        for used, name, value in ((self.uses_low, low_name, self.low),
                                  (self.uses_high, high_name, self.high)):
            if not used:
                continue
            if not math.isfinite(value):
                raise BandError(f'{name} ({value}) must be finite for {self.kind}')
            if value < 0:
                raise BandError(f'{name} ({value:g}) must not be negative')
            if self.by == 'index' and value != int(value):
                raise BandError(f'{name} ({value:g}) must be a whole mode number')
        if self.kind in ('bandpass', 'bandstop') and not self.low < self.high:
            if self.by == 'index' and self.low == self.high and self.kind == 'bandpass':
                return self  # a single mode
            raise BandError(f'{low_name} ({self.low:g}) must be below {high_name} '
                            f'({self.high:g}) for {self.kind}')
        return self

    def keeps(self, frequencies_hz: np.ndarray) -> np.ndarray:
        """Boolean mask of the modes (given by their frequencies, ascending) this band keeps."""
        f = np.asarray(frequencies_hz, dtype=float)
        x = np.arange(f.size, dtype=float) if self.by == 'index' else f
        if self.kind == 'allpass':
            return np.ones(f.size, dtype=bool)
        if self.kind == 'lowpass':
            return x <= self.high
        if self.kind == 'highpass':
            return x >= self.low
        if self.kind == 'bandpass':
            return (x >= self.low) & (x <= self.high)
        return (x < self.low) | (x > self.high)

    def describe(self) -> str:
        unit = ' Hz' if self.by == 'hz' else ''
        pre = 'modes ' if self.by == 'index' else ''
        if self.kind == 'allpass':
            return 'allpass'
        if self.kind == 'lowpass':
            return f'lowpass {pre}<= {self.high:g}{unit}'
        if self.kind == 'highpass':
            return f'highpass {pre}>= {self.low:g}{unit}'
        return f'{self.kind} {pre}{self.low:g}..{self.high:g}{unit}'

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

A band may also have a shape (:mod:`~modal_spring_ros.core.filter_response`): Butterworth
edges of an ``order``, gain terms in dB, damping ranges, and where the gains act (``acts_on``:
the streamed positions, or the loads). Shaped, it keeps the modes whose gain is at least
``GAIN_FLOOR`` (-60 dB).
"""
from __future__ import annotations

import dataclasses
import math
from typing import Mapping

from modal_spring_ros.core.filter_response import (ACTS_ON, butterworth, GAIN_FLOOR, MAX_ORDER,
                                                   parse_damping, parse_term, ResponseError,
                                                   widened_edge)
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
    #: Butterworth order of the edges (0: ideal edges, keep or drop)
    order: int = 0
    #: gain terms, as text (:func:`~modal_spring_ros.core.filter_response.parse_term`)
    gains: tuple[str, ...] = ()
    #: where the gains act: ``output`` (the streamed positions) or ``load`` (the modal loads)
    acts_on: str = 'output'
    #: damping ranges, as text (``LOW:HIGH:RATIO``)
    damping: tuple[str, ...] = ()

    def __post_init__(self):
        object.__setattr__(self, 'gains', tuple(str(x) for x in self.gains))
        object.__setattr__(self, 'damping', tuple(str(x) for x in self.damping))

    @property
    def shaped(self) -> bool:
        """Tell whether the band has a shape beyond keep-or-drop (edges, gains or damping)."""
        return bool(self.order or self.gains or self.damping)

    @property
    def top(self) -> float:
        """
        Return the highest edge the band needs modes up to, in its units.

        For rounded edges that is where the edge falls below the gain floor.
        """
        if not self.order:
            return self.high
        boost = sum(parse_term(t).most_db() for t in self.gains)
        return widened_edge(self.kind, self.low, self.high, self.order, boost)

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
            if not (self.by == 'index' and self.low == self.high and self.kind == 'bandpass'):
                raise BandError(f'{low_name} ({self.low:g}) must be below {high_name} '
                                f'({self.high:g}) for {self.kind}')
        self._validate_shape(names)
        return self

    def _validate_shape(self, names: Mapping[str, str]) -> None:
        order_name = names.get('order', 'order')
        if not (isinstance(self.order, (int, np.integer)) and 0 <= self.order <= MAX_ORDER):
            raise BandError(f'{order_name} ({self.order}) must be a whole number from 0 '
                            f'(ideal edges) to {MAX_ORDER}')
        if self.order and self.by != 'hz':
            raise BandError(f'{order_name} ({self.order}) rounds edges in Hz: it needs '
                            f"{names.get('by', 'by')} 'hz'")
        low_name, high_name = (names.get(field, field) for field in self.edge_fields())
        if self.order and self.kind in ('highpass', 'bandpass', 'bandstop') and self.low <= 0:
            raise BandError(f'{low_name} must be above 0 Hz for a rounded {self.kind} edge')
        if self.order and self.kind == 'lowpass' and self.high <= 0:
            raise BandError(f'{high_name} must be above 0 Hz for a rounded lowpass edge')
        if self.acts_on not in ACTS_ON:
            raise BandError(f"{names.get('acts_on', 'acts_on')} '{self.acts_on}' must be one "
                            f"of {', '.join(ACTS_ON)}")
        for field, parse in (('gains', parse_term), ('damping', parse_damping)):
            for text in getattr(self, field):
                try:
                    parse(text)
                except ResponseError as exc:
                    raise BandError(f'{names.get(field, field)}: {exc}') from None

    def gain(self, frequencies_hz: np.ndarray) -> np.ndarray:
        """
        Return each mode's gain: 1 as simulated, 2 doubled, 0 removed.

        Modes given by their frequencies, ascending: the edges' (1 inside, 0 outside for ideal
        edges) times the gain terms'.
        """
        f = np.asarray(frequencies_hz, dtype=float)
        if self.order:
            g = butterworth(self.kind, self.low, self.high, self.order, f)
        else:
            g = self._inside(f).astype(float)
        if self.gains:
            db = sum(parse_term(t).db_at(f) for t in self.gains)
            g = g * 10.0 ** (np.asarray(db, dtype=float) / 20.0)
        return g

    def keeps(self, frequencies_hz: np.ndarray) -> np.ndarray:
        """Boolean mask of the modes (given by their frequencies, ascending) this band keeps."""
        if self.order or self.gains:
            return self.gain(frequencies_hz) >= GAIN_FLOOR
        return self._inside(np.asarray(frequencies_hz, dtype=float))

    def _inside(self, f: np.ndarray) -> np.ndarray:
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
        shape = [f'order {self.order}'] if self.order else []
        if self.gains:
            shape.append(f"{self.acts_on} gains {' '.join(self.gains)}")
        if self.damping:
            shape.append(f"damping {' '.join(self.damping)}")
        return self._describe_edges() + ''.join(f', {x}' for x in shape)

    def _describe_edges(self) -> str:
        unit = ' Hz' if self.by == 'hz' else ''
        pre = 'modes ' if self.by == 'index' else ''
        if self.kind == 'allpass':
            return 'allpass'
        if self.kind == 'lowpass':
            return f'lowpass {pre}<= {self.high:g}{unit}'
        if self.kind == 'highpass':
            return f'highpass {pre}>= {self.low:g}{unit}'
        return f'{self.kind} {pre}{self.low:g}..{self.high:g}{unit}'

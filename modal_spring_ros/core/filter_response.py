"""
The filter's response: how strongly each mode takes part, as a curve over frequency.

The paper (section 2.1): in modal coordinates "specific mode components can be amplified or
removed". A band (:mod:`~modal_spring_ros.core.filter_band`) keeps or drops; a response
shapes. A mode of frequency ``f`` takes part with the gain

    g(f) = edges(f) * 10 ** (sum of the gain terms' dB at f / 20)

``edges`` is the band's: 1 inside and 0 outside for the ideal band (``order`` 0), or the
magnitude of a Butterworth filter of order ``n`` with the band's edges as its -3 dB points
(``order`` n):

==========  ==========================================
type        x (the magnitude is 1 / sqrt(1 + x^(2n)))
==========  ==========================================
lowpass     f / high
highpass    low / f
bandpass    (f^2 - low high) / (f (high - low))
bandstop    f (high - low) / (f^2 - low high)
==========  ==========================================

Gain terms, each written as text (the node's ``filter.gains``, ``--gain`` on the command line):

- ``LOW:HIGH:DB``: DB over ``LOW <= f <= HIGH`` Hz, 0 dB elsewhere (+6.02 dB doubles);
- ``peak:CENTER:WIDTH:DB``: a bell, DB at CENTER and half of it at CENTER +- WIDTH/2 Hz;
- ``low_shelf:CORNER:DB`` / ``high_shelf:CORNER:DB``: DB far below (above) CORNER Hz, half of
  it at CORNER.

Damping ranges (``filter.damping``, ``--damping-ratio``), ``LOW:HIGH:RATIO``: modes in
``LOW <= f <= HIGH`` Hz are damped with the modal ratio RATIO (``C_i = 2 h_i omega_i``, the
paper's eq. 14) instead of the scene's damping; a later range wins where two overlap.

A mode whose gain is below :data:`GAIN_FLOOR` (-60 dB) is not stepped, as a mode outside an
ideal band is not.
"""
from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np

#: a mode whose gain is below this (-60 dB) is left out of the run
GAIN_FLOOR = 1e-3
#: highest Butterworth order of the band's edges
MAX_ORDER = 16
#: largest gain or attenuation one term gives, dB
MAX_TERM_DB = 60.0
#: where the gains act: on the streamed positions, or on the loads that drive each mode
ACTS_ON = ('output', 'load')
#: the shapes a gain term has (``range`` is written without its name)
TERM_KINDS = ('range', 'peak', 'low_shelf', 'high_shelf')
#: largest modal damping ratio a range sets (critical damping)
MAX_DAMPING_RATIO = 1.0


class ResponseError(ValueError):
    """An impossible response; the message names the term and the rule."""


@dataclasses.dataclass(frozen=True)
class GainTerm:
    """One term of the response, in dB over frequency (see the module's text)."""

    kind: str
    a: float        # range: LOW; peak: CENTER; shelves: CORNER (Hz)
    b: float        # range: HIGH; peak: WIDTH (Hz); shelves: unused
    db: float

    def db_at(self, f: np.ndarray) -> np.ndarray:
        """Return the term's gain in dB at frequencies ``f`` (Hz)."""
        f = np.asarray(f, dtype=float)
        if self.kind == 'range':
            return np.where((f >= self.a) & (f <= self.b), self.db, 0.0)
        if self.kind == 'peak':
            return self.db / (1.0 + ((f - self.a) / (0.5 * self.b)) ** 2)
        a2, f2 = self.a * self.a, f * f
        if self.kind == 'low_shelf':
            return self.db * a2 / (a2 + f2)
        return self.db * f2 / (a2 + f2)

    def most_db(self) -> float:
        """Return the largest boost the term gives anywhere (0 for a cut)."""
        return max(self.db, 0.0)


@dataclasses.dataclass(frozen=True)
class DampingRange:
    """Modes in ``low <= f <= high`` Hz are damped with the modal ratio ``ratio``."""

    low: float
    high: float
    ratio: float


def _numbers(text: str, fields: list[str], what: str) -> list[float]:
    if len(fields) != sum(1 for x in what.split(':') if x.isupper()):
        raise ResponseError(f"'{text}' must be written {what}")
    try:
        values = [float(x) for x in fields]
    except ValueError:
        raise ResponseError(f"'{text}' must be written {what} (numbers)") from None
    if not all(math.isfinite(v) for v in values):
        raise ResponseError(f"'{text}': every number must be finite")
    return values


@functools.lru_cache(maxsize=256)
def parse_term(text: str) -> GainTerm:
    """Return the gain term ``text`` names (see the module's text); :class:`ResponseError`."""
    fields = [x.strip() for x in str(text).split(':')]
    kind = fields[0].lower() if fields and fields[0][:1].isalpha() else 'range'
    if kind == 'range':
        low, high, db = _numbers(text, fields, 'LOW:HIGH:DB')
        if not 0.0 <= low < high:
            raise ResponseError(f"'{text}': LOW ({low:g} Hz) must be at least 0 and below "
                                f'HIGH ({high:g} Hz)')
        term = GainTerm('range', low, high, db)
    elif kind == 'peak':
        center, width, db = _numbers(text, fields[1:], 'peak:CENTER:WIDTH:DB')
        if not (center > 0.0 and width > 0.0):
            raise ResponseError(f"'{text}': CENTER and WIDTH must be above 0 Hz")
        term = GainTerm('peak', center, width, db)
    elif kind in ('low_shelf', 'high_shelf'):
        corner, db = _numbers(text, fields[1:], f'{kind}:CORNER:DB')
        if not corner > 0.0:
            raise ResponseError(f"'{text}': CORNER ({corner:g} Hz) must be above 0 Hz")
        term = GainTerm(kind, corner, 0.0, db)
    else:
        raise ResponseError(f"gain term '{text}': '{fields[0]}' is not one of "
                            f"{', '.join(TERM_KINDS[1:])} (or LOW:HIGH:DB for a range)")
    if abs(term.db) > MAX_TERM_DB:
        raise ResponseError(f"'{text}': {term.db:g} dB is beyond +-{MAX_TERM_DB:g} dB")
    return term


@functools.lru_cache(maxsize=256)
def parse_damping(text: str) -> DampingRange:
    """Return the damping range ``text`` names (``LOW:HIGH:RATIO``); :class:`ResponseError`."""
    low, high, ratio = _numbers(text, [x.strip() for x in str(text).split(':')],
                                'LOW:HIGH:RATIO')
    if not 0.0 <= low <= high:
        raise ResponseError(f"damping '{text}': LOW ({low:g} Hz) must be at least 0 and not "
                            f'above HIGH ({high:g} Hz)')
    if not 0.0 <= ratio <= MAX_DAMPING_RATIO:
        raise ResponseError(f"damping '{text}': RATIO ({ratio:g}) must be from 0 to "
                            f'{MAX_DAMPING_RATIO:g} (critical damping)')
    return DampingRange(low, high, ratio)


def damping_ratios(ranges: tuple[str, ...], frequencies_hz: np.ndarray) -> np.ndarray:
    """Return the damping ratio ``ranges`` give each frequency (NaN: none, the scene's)."""
    f = np.asarray(frequencies_hz, dtype=float)
    out = np.full(f.size, np.nan)
    for text in ranges:
        r = parse_damping(text)
        out[(f >= r.low) & (f <= r.high)] = r.ratio
    return out


def split_terms(text: str) -> tuple[str, ...]:
    """Return the terms of a list written as one string (separated by commas or spaces)."""
    return tuple(x for x in str(text).replace(',', ' ').split() if x)


def butterworth(kind: str, low: float, high: float, order: int,
                f: np.ndarray) -> np.ndarray:
    """Return the magnitude of a Butterworth ``kind`` filter of ``order`` at ``f`` (Hz)."""
    f = np.asarray(f, dtype=float)
    if kind == 'allpass' or order <= 0:
        return np.ones(f.size)
    with np.errstate(divide='ignore', invalid='ignore'):
        if kind == 'lowpass':
            x = f / high
        elif kind == 'highpass':
            x = np.where(f > 0.0, low / np.where(f > 0.0, f, 1.0), np.inf)
        else:
            num, den = f * f - low * high, f * (high - low)
            x = num / den if kind == 'bandpass' else den / num
        x = np.where(np.isnan(x), np.inf, np.abs(x))
        return 1.0 / np.sqrt(1.0 + x ** (2 * order))


def widened_edge(kind: str, low: float, high: float, order: int, boost_db: float) -> float:
    """
    Return the highest frequency where an order-``order`` edge still passes :data:`GAIN_FLOOR`.

    With ``boost_db`` of gain terms on top (Hz; ``high`` itself for an ideal band).
    """
    if order <= 0:
        return high
    floor = GAIN_FLOOR / 10.0 ** (boost_db / 20.0)
    x = (1.0 / floor ** 2 - 1.0) ** (1.0 / (2 * order)) if floor < 1.0 else 1.0
    if kind == 'lowpass':
        return high * x
    width = high - low      # bandpass: the upper root of f^2 - x width f - low high = 0
    return 0.5 * (x * width + math.sqrt((x * width) ** 2 + 4.0 * low * high))

"""The filter's response drawn: gain (dB) against frequency, with the scene's modes marked."""
from __future__ import annotations

from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.filter_response import GAIN_FLOOR
import numpy as np

#: the chart's lowest gain, dB (the floor below which a mode is left out, and a little more)
FLOOR_DB = 20.0 * np.log10(GAIN_FLOOR) - 10.0


def draw_response(band: FilterBand, frequencies_hz: np.ndarray, path: str,
                  title: str = '') -> None:
    """
    Write a PNG of ``band``'s gain over the modes' range, each mode a marker at its gain.

    Modes left out (below the floor) are drawn on the chart's bottom edge.
    """
    # deferred on purpose: matplotlib takes ~0.5 s to import and only the chart needs it
    from matplotlib.figure import Figure  # no pyplot: no display, no global figure state
    f = np.asarray(frequencies_hz, dtype=float)
    top = float(f.max()) * 1.2 if f.size else 1.0
    curve_f = np.geomspace(max(top * 1e-4, 1e-3), top, 2000)
    if band.by == 'index':
        curve_f = f          # the band is in mode numbers: it has a value only at each mode
    with np.errstate(divide='ignore'):
        curve = np.maximum(20.0 * np.log10(band.gain(curve_f)), FLOOR_DB)
        modes = np.maximum(20.0 * np.log10(band.gain(f)), FLOOR_DB)
    fig = Figure(figsize=(8, 4.5), dpi=100)
    ax = fig.add_subplot()
    ax.semilogx(curve_f, curve, color='tab:blue', label=f'response ({band.acts_on} gains)')
    kept = band.keeps(f)
    ax.plot(f[kept], modes[kept], 'o', color='tab:orange', ms=4, label='modes stepped')
    ax.plot(f[~kept], modes[~kept], 'x', color='tab:gray', ms=4, label='modes left out')
    ax.axhline(-3.0103, color='tab:gray', lw=0.5, ls=':')
    ax.set_ylim(FLOOR_DB - 2.0, max(6.0, float(curve.max()) + 3.0))
    ax.set_xlabel('frequency, Hz')
    ax.set_ylabel('gain, dB')
    ax.set_title(title or band.describe(), fontsize=9)
    ax.grid(True, which='both', alpha=0.3)
    ax.legend(fontsize=8, loc='lower left')
    fig.tight_layout()
    fig.savefig(path)

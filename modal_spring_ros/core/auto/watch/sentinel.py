"""
The watch's sentinel: a window started as soon as the run's motion outgrows what was measured.

A watched window, like the pilot's from rest, measures the plan over the states the run goes
through in it; between two windows the run is not measured, and the interval between them is
long (10 s by default, far longer where the shadows are dear). A reduced plan's error does not
grow with time as such but with the motion: a shake that builds up, a pull, a clamp driven
harder take the run to amplitudes no window saw, and the error of a basis that leaves out
modes, nonlinear terms or springs grows with them (``sheet_10x10`` shaken ever harder near its
vertical mode: 0.4 % while the motion is within twice the pilot's largest, 1.1 % at 6.6 times,
10 % and more beyond: ``docs/speed.md``).

So the sentinel keeps the envelope of what was measured: the largest mass-weighted sizes of the
displacement and of the velocity in the clamp's frame (``sqrt(u^T M u)``, ``sqrt(v^T M v)``,
:meth:`~modal_spring_ros.core.simulations.Simulation.motion_size`: a modal run's from its
coordinates alone) over the samples the pilot's window and every watched window covered. Between
windows it reads the run's own, once a sample, and a sample beyond ``RISE`` times the envelope
starts a window at once. Where a plan's error comes from what its basis leaves out, it grows
about in proportion to the motion: a plan measured within T is measured again before the motion
has doubled, so before that could take it past 2 T. Each window it starts raises the envelope
by ``RISE`` at least, so a run whose motion grows by a factor ``G`` starts at most
``log2(G)`` windows of each kind this way: a bounded cost, whatever the watch's budget.
"""
from __future__ import annotations

import math

from modal_spring_ros.core.simulations import Simulation
import numpy as np

#: A sample whose displacement or velocity is beyond this times the largest measured starts a
#: window.
RISE = 2.0
#: The envelope starts at this share of the scene's size (its extent times the square root of
#: its mass, and that over the window for velocity): a run that barely moves is not watched for
#: round-off.
FLOOR = 1e-6


def floor(sim: Simulation, window_s: float) -> np.ndarray:
    """Return the least envelope of ``sim``'s scene: ``FLOOR`` of its size (see FLOOR)."""
    rest = sim.model.rest
    extent = float(np.max(np.ptp(rest, axis=0))) if rest.size else 1.0
    size = FLOOR * extent * math.sqrt(float(np.sum(sim.model.mass_dof)))
    return np.array([size, size / window_s])


class Sentinel:
    """
    Tell when the run's motion leaves the envelope of what was measured (see the module).

    ``sample_s``: how often the run is read; ``window_s``: a window's span (the velocity's floor
    is the displacement's over it).
    """

    def __init__(self, sample_s: float, window_s: float):
        self.sample_s, self.window_s = float(sample_s), float(window_s)
        #: the largest displacement and velocity sizes measured (at least the floor; None:
        #: before the first sample)
        self.envelope: np.ndarray | None = None
        #: the sizes beyond the envelope that started the last window, and how many it started
        self.beyond: np.ndarray | None = None
        self.started = 0
        #: when the run is read next (a caller stepping one step at a time checks it first)
        self.next_s = -math.inf

    def restart(self) -> None:
        """Read the run again from its next sample (a reset); the envelope is kept."""
        self.next_s = -math.inf

    def outgrown(self, sim: Simulation, measured: bool) -> bool:
        """
        Read ``sim`` when a sample is due; tell whether its motion outgrew the envelope.

        ``measured``: the run is within a span a window (or the pilot's) measures: its motion
        widens the envelope. Outside, a motion beyond ``RISE`` times the envelope is outgrown:
        the window that starts now measures it (the envelope takes it).
        """
        if sim.time + 0.5 * sim.dt < self.next_s:
            return False
        self.next_s = sim.time + self.sample_s
        if self.envelope is None:
            self.envelope = floor(sim, self.window_s)
        size = np.array(sim.motion_size())
        if not np.all(np.isfinite(size)):
            return False                        # a diverged run is the run's report, not ours
        outgrown = not measured and bool(np.any(size > RISE * self.envelope))
        if outgrown:
            self.beyond, self.started = size / self.envelope, self.started + 1
        if measured or outgrown:
            np.maximum(self.envelope, size, out=self.envelope)
        return outgrown

    def describe_beyond(self) -> str:
        """Say how far the motion outgrew the envelope when it last started a window."""
        if self.beyond is None:
            return ''
        which = 'displacement' if self.beyond[0] >= self.beyond[1] else 'velocity'
        return f'its {which} {float(np.max(self.beyond)):.3g} times the largest measured'

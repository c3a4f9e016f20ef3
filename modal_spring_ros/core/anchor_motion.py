"""Prescribed motion of a scene's fixed particles: a sum of sines, optionally ramped in.

Every fixed particle follows the same offset from its rest position, so the fixed particles
move as one rigid base (a shaken clamp). The simulation composes this rigid motion with the
springs' motion, as the paper suggests for its fixed particles: every particle rides along with
the base, ``x = x_rest + offset(t) + u``, and the free displacement ``u`` feels the inertial
load ``-m * offset''(t)`` (base excitation). Since a rigid shift stretches no spring, this is
exact, and the modes computed with the anchors held still stay valid while they move.
"""
from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np


@dataclasses.dataclass(frozen=True)
class SineComponent:
    """``amplitude * sin(2 pi f t + phase)`` along ``axis`` (0 = x, 1 = y, 2 = z).

    ``ramp_s`` > 0 multiplies the component by a ramp from 0 to 1 over the first ``ramp_s``
    seconds: the quintic smoothstep ``r = 10 x^3 - 15 x^4 + 6 x^5`` (``x = t / ramp_s``), whose
    first and second derivatives vanish at both ends. The base's velocity and acceleration, and
    so the load ``-m * offset''``, are then continuous at the start and the end of the ramp,
    whatever the phase: no step load, which would excite every mode at once.
    """

    axis: int
    amplitude: float
    frequency_hz: float
    phase: float = 0.0
    ramp_s: float = 0.0


@dataclasses.dataclass(frozen=True)
class AnchorMotion:
    components: tuple[SineComponent, ...]

    @property
    def is_static(self) -> bool:
        return not self.components or all(c.amplitude == 0.0 for c in self.components)

    @property
    def frequencies_hz(self) -> np.ndarray:
        """Frequencies the motion contains (the driving spectrum), Hz."""
        return np.array([c.frequency_hz for c in self.components if c.amplitude != 0.0])

    def offset(self, t: float) -> np.ndarray:
        """(3,) displacement of every fixed particle from its rest position at time ``t``."""
        return self._derivative(t, 0)

    def velocity(self, t: float) -> np.ndarray:
        """(3,) velocity of the fixed particles at time ``t``."""
        return self._derivative(t, 1)

    def acceleration(self, t: float) -> np.ndarray:
        """(3,) acceleration of the fixed particles at time ``t`` (the base excitation)."""
        return self._derivative(t, 2)

    @functools.cached_property
    def _terms(self) -> tuple[tuple[int, float, float, float, float], ...]:
        """Per component: axis, amplitude, angular frequency, phase, ramp time."""
        return tuple((c.axis, c.amplitude, 2.0 * math.pi * c.frequency_hz, c.phase, c.ramp_s)
                     for c in self.components)

    def _derivative(self, t: float, order: int) -> np.ndarray:
        """``order``-th time derivative of ``ramp(t) * A sin(w t + phase)``, summed.

        Evaluated in Python floats (a few components; called on every step)."""
        out = [0.0, 0.0, 0.0]
        for axis, amplitude, w, phase, ramp_s in self._terms:
            s = amplitude * math.sin(w * t + phase)
            ds = amplitude * w * math.cos(w * t + phase) if order else 0.0
            dds = -w * w * s
            if t >= ramp_s:  # past the ramp, or no ramp (ramp_s = 0)
                out[axis] += (s, ds, dds)[order]
                continue
            x = max(t, 0.0) / ramp_s  # quintic smoothstep and its derivatives in t
            r = x * x * x * (10.0 + x * (-15.0 + 6.0 * x))
            dr = 30.0 * x * x * (1.0 - x) ** 2 / ramp_s
            ddr = 60.0 * x * (1.0 - x) * (1.0 - 2.0 * x) / (ramp_s * ramp_s)
            if order == 0:
                out[axis] += r * s
            elif order == 1:
                out[axis] += dr * s + r * ds
            else:
                out[axis] += ddr * s + 2.0 * dr * ds + r * dds
        return np.array(out)

    def to_list(self) -> list[dict]:
        return [{"axis": "xyz"[c.axis], "amplitude": c.amplitude,
                 "frequency_hz": c.frequency_hz, "phase": c.phase, "ramp_s": c.ramp_s}
                for c in self.components]

"""
Prescribed motion of a scene's fixed particles.

Sums of sines, optionally ramped in, that translate the clamp and turn it about axes through
pivots.

Every fixed particle moves with one rigid motion ``x = R(t) X + b(t)`` (a shaken, turning
clamp). Translation terms add up to an offset ``p(t)``; rotation terms turn about an axis
through their pivot by ``angle(t)``, in the order they are listed, and the offset is added
last. The simulation composes this rigid motion with the springs' motion: every particle rides
along with the clamp, ``x = R (X + u) + b``, and the displacement ``u`` in the clamp's frame
feels the frame's inertial loads. For a clamp that only translates the load is
``-m * p''(t)`` (base excitation; a rigid shift stretches no spring, so this is exact); a
turning clamp adds the centrifugal, Euler and Coriolis loads and turns gravity
(:mod:`modal_spring_ros.core.motion.frame_loads`). The modes computed with the clamp held still
stay valid in its frame while it moves.
"""
from __future__ import annotations

import dataclasses
import functools
import math
from typing import ClassVar

from modal_spring_ros.core.motion.rigid_frame import axis_rotation, cross_matrix, RigidFrame
import numpy as np


def ramped_sine(t: float, amplitude: float, w: float, phase: float, ramp_s: float
                ) -> tuple[float, float, float]:
    """
    ``ramp(t) * A sin(w t + phase)`` and its first and second time derivatives.

    The ramp is the quintic smoothstep ``r = 10 x^3 - 15 x^4 + 6 x^5`` (``x = t / ramp_s``)
    over the first ``ramp_s`` seconds (none when 0), whose first and second derivatives vanish
    at both ends: the motion's velocity and acceleration are continuous, whatever the phase.
    Python floats (called on every step).
    """
    s = amplitude * math.sin(w * t + phase)
    ds = amplitude * w * math.cos(w * t + phase)
    dds = -w * w * s
    if t >= ramp_s:  # past the ramp, or no ramp (ramp_s = 0)
        return s, ds, dds
    x = max(t, 0.0) / ramp_s
    r = x * x * x * (10.0 + x * (-15.0 + 6.0 * x))
    dr = 30.0 * x * x * (1.0 - x) ** 2 / ramp_s
    # divided twice: a ramp shorter than 1e-154 s has a square that underflows to 0
    ddr = 60.0 * x * (1.0 - x) * (1.0 - 2.0 * x) / ramp_s / ramp_s
    return r * s, dr * s + r * ds, ddr * s + 2.0 * dr * ds + r * dds


@dataclasses.dataclass(frozen=True)
class SineComponent:
    """
    ``amplitude * sin(2 pi f t + phase)`` along ``axis`` (0 = x, 1 = y, 2 = z), m.

    ``ramp_s`` > 0 ramps it in over the first ``ramp_s`` seconds (see :func:`ramped_sine`): no
    step load, which would excite every mode at once.
    """

    axis: int
    amplitude: float
    frequency_hz: float
    phase: float = 0.0
    ramp_s: float = 0.0


@dataclasses.dataclass(frozen=True)
class RotationComponent:
    """
    A turn by ``amplitude * sin(2 pi f t + phase)`` (rad) about world axis ``axis``.

    A turn by ``amplitude * sin(2 pi f t + phase)`` (rad) about world axis ``axis`` through
    ``pivot`` (3,), ramped in over ``ramp_s`` seconds like a :class:`SineComponent`.
    """

    axis: int
    amplitude: float
    frequency_hz: float
    pivot: tuple[float, float, float]
    phase: float = 0.0
    ramp_s: float = 0.0


@dataclasses.dataclass(frozen=True)
class AnchorMotion:
    """
    The clamp's rigid motion.

    Translation terms (summed) and rotation terms (composed in the order listed, the translation
    added last).
    """

    components: tuple[SineComponent, ...]
    rotations: tuple[RotationComponent, ...] = ()
    #: changes when the motion does (a function of time alone: never)
    revision: ClassVar[int] = 0

    def restart(self) -> None:
        """Go back to t = 0 with the run (a function of time has nothing to restart)."""

    def clear(self) -> None:
        """Forget what the motion was given (``~/reset``; a function of time was given nothing)."""

    @property
    def is_static(self) -> bool:
        return all(c.amplitude == 0.0 for c in (*self.components, *self.rotations))

    @property
    def rotates(self) -> bool:
        """Tell whether the clamp turns (the run needs the floating frame's inertial loads)."""
        return any(c.amplitude != 0.0 for c in self.rotations)

    @property
    def frequencies_hz(self) -> np.ndarray:
        """Frequencies the motion contains (the driving spectrum), Hz."""
        return np.array([c.frequency_hz for c in (*self.components, *self.rotations)
                         if c.amplitude != 0.0])

    @property
    def rotation_frequencies_hz(self) -> np.ndarray:
        """Frequencies the clamp turns at, Hz."""
        return np.array([c.frequency_hz for c in self.rotations if c.amplitude != 0.0])

    def offset(self, t: float) -> np.ndarray:
        """(3,) translation ``p(t)`` of the clamp (the whole motion when it does not turn)."""
        return self._translation(t)[0]

    def velocity(self, t: float) -> np.ndarray:
        """(3,) ``p'(t)``."""
        return self._translation(t)[1]

    def acceleration(self, t: float) -> np.ndarray:
        """(3,) ``p''(t)`` (the base excitation of a clamp that only translates)."""
        return self._translation(t)[2]

    def frame(self, t: float) -> RigidFrame:
        """Return the whole rigid motion ``x = R X + b`` at ``t``, with its rates."""
        frame = None
        for axis, amplitude, w, phase, ramp_s, pivot, e, ee in self._turns:
            angle, rate, acceleration = ramped_sine(t, amplitude, w, phase, ramp_s)
            q = axis_rotation(axis, angle)  # Q' = rate [e]x Q, Q'' = (acc [e]x + rate^2 [e]x^2) Q
            turn = RigidFrame.turn(q, rate * (e @ q), (acceleration * e + rate * rate * ee) @ q,
                                   pivot)
            frame = turn if frame is None else frame.then(turn)
        return (frame or RigidFrame.identity()).translated(*self._translation(t))

    @functools.cached_property
    def _terms(self) -> tuple[tuple[int, float, float, float, float], ...]:
        """Per translation term: axis, amplitude, angular frequency, phase, ramp time."""
        return tuple((c.axis, c.amplitude, 2.0 * math.pi * c.frequency_hz, c.phase, c.ramp_s)
                     for c in self.components)

    @functools.cached_property
    def _turns(self) -> tuple[tuple, ...]:
        """
        Return what each rotation term needs at every call, computed once.

        Per term: axis, amplitude, angular frequency, phase, ramp time, pivot, ``[e]x`` and
        ``[e]x^2`` of its axis.
        """
        return tuple((c.axis, c.amplitude, 2.0 * math.pi * c.frequency_hz, c.phase, c.ramp_s,
                      np.array(c.pivot, dtype=float), cross_matrix(c.axis),
                      cross_matrix(c.axis) @ cross_matrix(c.axis)) for c in self.rotations)

    def _translation(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``p``, ``p'`` and ``p''`` at ``t``, each (3,)."""
        out = np.zeros((3, 3))
        for axis, amplitude, w, phase, ramp_s in self._terms:
            out[:, axis] += ramped_sine(t, amplitude, w, phase, ramp_s)
        return out[0], out[1], out[2]

    def to_list(self) -> list[dict]:
        translations = [{'axis': 'xyz'[c.axis], 'amplitude': c.amplitude,
                         'frequency_hz': c.frequency_hz, 'phase': c.phase, 'ramp_s': c.ramp_s}
                        for c in self.components]
        turns = [{'rotation': 'xyz'[c.axis], 'amplitude_deg': math.degrees(c.amplitude),
                  'frequency_hz': c.frequency_hz, 'phase': c.phase, 'ramp_s': c.ramp_s,
                  'pivot': list(c.pivot)} for c in self.rotations]
        return translations + turns

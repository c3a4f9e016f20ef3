"""
How long the pilot's window is: what a plan is measured over before it is trusted.

A few periods of the slowest kept mode and of the clamp's drive, so that the window sees what
the scene excites; and where the drive is near a kept mode, the time that mode's response takes
to build up (a resonance): the plan's error builds up with it, faster than the drift model
fitted to a shorter window extrapolates (:func:`~.measured_error.horizon_error`).
"""
from __future__ import annotations

from modal_spring_ros.core.model.model import MassSpringModel
import numpy as np

#: Pilot window bounds, s, and how many periods of the slowest kept mode and of the drive it spans
#: (a drive near a resonance builds its error up over several periods).
MIN_WINDOW_S, MAX_WINDOW_S, WINDOW_PERIODS = 1.0, 3.0, 8.0
#: A drive within this share of a kept mode's frequency builds that mode up (a resonance: an
#: undamped mode 10 % off its drive responds five times as far as the drive's static pull);
#: the window then spans ``BUILD_UP_SETTLING`` times its settling time (the mode's decay time or
#: the beat's period, the shorter), up to ``MAX_BUILD_UP_WINDOW_S`` and the run's horizon.
#: Measured: a sheet driven at its first mode (damping ratio 0.02, decay time 1.7 s) built its
#: plan's error up from 0.26 % over 1.7 s to 1.1 % over 5 s, where a drift fitted to the 1.7 s
#: window promised 0.55 %.
NEAR_DRIVE, BUILD_UP_SETTLING, MAX_BUILD_UP_WINDOW_S = 0.1, 3.0, 8.0


def pilot_window(model: MassSpringModel, kept_hz: np.ndarray) -> float:
    """
    Return the pilot window for the modes of ``kept_hz`` (Hz).

    A few periods of the slowest kept mode and of the drive, or a drive's build-up near a kept
    mode (:func:`build_up_s`) where that is longer.
    """
    drive = [f for f in model.motion.frequencies_hz.tolist() if f > 0]
    slowest = min([float(np.min(kept_hz)), *drive])
    window = WINDOW_PERIODS / slowest if slowest > 0 else MAX_WINDOW_S
    window = min(MAX_WINDOW_S, max(MIN_WINDOW_S, window))
    return float(max(window, min(MAX_BUILD_UP_WINDOW_S, build_up_s(model, kept_hz))))


def build_up_s(model: MassSpringModel, kept_hz: np.ndarray) -> float:
    """
    Return how long the clamp's drive takes to build up its response in the kept modes, s.

    A drive within ``NEAR_DRIVE`` of a kept mode's frequency builds that mode up, and with it
    the plan's error (a small error in the mode's frequency changes how far it builds), until
    its damping or the beat with the drive stops it: over ``BUILD_UP_SETTLING`` times the
    shorter of the mode's decay time and the beat's period. 0 with no drive near a mode.
    """
    drive = model.motion.frequencies_hz
    kept = np.asarray(kept_hz, dtype=float)
    if not drive.size or not kept.size:
        return 0.0
    decay = 0.5 * model.scene.damping.modal_coefficients(2.0 * np.pi * kept)   # 1/s
    apart = np.abs(drive[:, None] - kept[None, :])                              # Hz
    near = (drive[:, None] > 0) & (apart <= NEAR_DRIVE * kept[None, :])
    if not near.any():
        return 0.0
    with np.errstate(divide='ignore'):
        settle = np.minimum(1.0 / np.broadcast_to(decay, apart.shape), 1.0 / apart)
    return float(BUILD_UP_SETTLING * settle[near].max())

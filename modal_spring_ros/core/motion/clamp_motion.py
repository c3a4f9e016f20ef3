"""
What a run asks of its clamp's motion, wherever the motion comes from.

Two kinds fill it: a scene's own prescribed motion
(:class:`~modal_spring_ros.core.motion.anchor_motion.AnchorMotion`, data, part of the scene) and
a clamp that follows the poses a run is given
(:class:`~modal_spring_ros.core.motion.clamp_follower.ClampFollower`, input state, held by the
run's model and cleared with the run). A third kind (a clamp driven by a trajectory file, by a
joint) is a class with these members, handed to
:class:`~modal_spring_ros.core.model.model.MassSpringModel`.
"""
from __future__ import annotations

from typing import Protocol

from modal_spring_ros.core.motion.rigid_frame import RigidFrame
import numpy as np


class ClampMotion(Protocol):
    """The rigid motion of every fixed particle, ``x = R(t) X + b(t)``."""

    #: translation terms (sines) a base excitation is predicted from; () where none are known
    components: tuple
    #: changes whenever the motion changes for a time already asked (a new pose)
    revision: int

    @property
    def rotates(self) -> bool:
        """Tell whether the clamp may turn (displacements then live in its frame)."""

    @property
    def is_static(self) -> bool:
        """Tell whether the clamp never moves."""

    @property
    def frequencies_hz(self) -> np.ndarray:
        """Return the frequencies the clamp is driven at (Hz; its bandwidth for a follower)."""

    @property
    def rotation_frequencies_hz(self) -> np.ndarray:
        """Return the frequencies of its turns (Hz)."""

    def frame(self, t: float) -> RigidFrame:
        """Return the clamp's rigid motion at ``t`` (rotation, translation and their rates)."""

    def offset(self, t: float) -> np.ndarray:
        """Return the (3,) translation at ``t``."""

    def restart(self) -> None:
        """Go back to ``t = 0`` with the run."""

    def clear(self) -> None:
        """Forget what it was given (a reset): at rest at its home pose."""

    def to_list(self) -> list:
        """Return its scene-file form (a follower: none)."""

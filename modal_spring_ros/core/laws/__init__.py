"""
Spring laws: how a spring pulls as a function of its length.

A contract (:class:`SpringLaw`: the tension, its two derivatives and the energy; the force, the
tangent, the rest stiffness and the tangent's derivative follow from them once, in the
contract), a name-to-class registry, one law a module. The force models, the stiffness
assembly, the modal derivatives, the loaded shape and the energy all ask a scene's law
(:func:`scene_law`); none writes a spring's formula itself.

* ``linear`` (:class:`LinearSpring`): the paper's Hooke spring, ``f = k (L - l)``.

To add a law: a module with a :class:`SpringLaw` subclass and its entry in
:data:`SPRING_LAWS`; a scene then names it (``springs: {law: <name>}``).
"""
from __future__ import annotations

from modal_spring_ros.core.laws.base import SpringLaw
from modal_spring_ros.core.laws.linear import LinearSpring
import numpy as np

#: law name -> class
SPRING_LAWS: dict[str, type[SpringLaw]] = {cls.name: cls for cls in (LinearSpring,)}
#: the law of a scene that names none
DEFAULT_LAW = LinearSpring.name


def spring_law(name: str, stiffness: np.ndarray, rest_length: np.ndarray) -> SpringLaw:
    """Return the law ``name`` bound to the springs. Raises ValueError naming the choices."""
    try:
        cls = SPRING_LAWS[name]
    except KeyError:
        raise ValueError(f"spring law '{name}' must be one of {', '.join(SPRING_LAWS)}") from None
    return cls(stiffness, rest_length)


def scene_law(scene) -> SpringLaw:
    """Return the law of ``scene``'s springs, bound to their stiffness and rest length."""
    return spring_law(scene.spring_law, scene.stiffness, scene.rest_length)


__all__ = ['DEFAULT_LAW', 'LinearSpring', 'SPRING_LAWS', 'SpringLaw', 'scene_law', 'spring_law']

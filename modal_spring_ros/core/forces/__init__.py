"""
Force models: how the spring forces of a set of coordinates are evaluated.

A contract (:class:`ForceModel`: the force for a state, its cost, its report, what it needs
trained), a name-to-class registry (:data:`FORCES`), one model a module:

* ``exact`` (:class:`ExactForces`): every spring on every step, the paper's method.
* ``refreshed`` (:class:`RefreshedForces`): every spring every N steps, the static tangent
  between.
* ``sampled`` (:class:`SampledForces`): a weighted sample of the springs on every step (ECSW).

A new model is one module with a :class:`ForceModel` subclass and one line below.
"""
from __future__ import annotations

from modal_spring_ros.core.forces.base import ForceContext, ForceModel, ForceOptions, ForceReport
from modal_spring_ros.core.forces.exact import ExactForces
from modal_spring_ros.core.forces.refreshed import RefreshedForces
from modal_spring_ros.core.forces.sampled import SampledForces

#: model name -> class
FORCES: dict[str, type[ForceModel]] = {
    cls.name: cls for cls in (ExactForces, RefreshedForces, SampledForces)}


def force_model(options: ForceOptions) -> type[ForceModel]:
    """
    Return the class ``options.model`` names (options validated).

    :raises ValueError: an unknown model, or options out of range.
    """
    options.validate()
    try:
        return FORCES[options.model]
    except KeyError:
        raise ValueError(f"force model '{options.model}' must be one of "
                         f"{', '.join(FORCES)}") from None


def build_forces(context: ForceContext, options: ForceOptions) -> ForceModel:
    """Return the force model ``options`` name for the coordinates of ``context``."""
    return force_model(options).build(context, options)


__all__ = ['FORCES', 'ExactForces', 'ForceContext', 'ForceModel', 'ForceOptions', 'ForceReport',
           'RefreshedForces', 'SampledForces', 'build_forces', 'force_model']

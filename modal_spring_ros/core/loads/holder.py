"""
A run that holds its loads: one per name, replaced whole, cleared by a reset, handed over whole.

Every simulation is a :class:`LoadHolder` (:mod:`~modal_spring_ros.core.simulations.base`):
its steps add the forces of :attr:`LoadHolder.loads` through the seat
(:mod:`~modal_spring_ros.core.loads.applied`), its reset clears them, and a run that takes over
from another (a settings change, a watch's shadow runs) takes every one of them.
"""
from __future__ import annotations

from modal_spring_ros.core.loads.base import Load
from modal_spring_ros.core.loads.contact import ContactLoad
from modal_spring_ros.core.loads.pull import Pull
from modal_spring_ros.core.loads.wrench import AppliedWrench
from modal_spring_ros.core.model.colliders import Pose


class LoadHolder:
    """The loads a run holds, by name (:class:`~modal_spring_ros.core.loads.base.Load`)."""

    #: what acts on the particles from outside the scene, by name (a new dict on every change,
    #: so that a copy handed over is never changed under its holder)
    loads: dict[str, Load] = {}

    def set_load(self, name: str, load: Load | None) -> None:
        """Apply ``load`` under ``name`` from now on (None: remove it). A reset ends it too."""
        if load is None:
            self.loads = {k: v for k, v in self.loads.items() if k != name}
        elif load.name != name:
            raise ValueError(f'a {load.name} load set as {name!r}')
        else:
            self.loads = {**self.loads, name: load}

    @property
    def pull(self) -> Pull | None:
        """Return the pull on a particle (:mod:`~modal_spring_ros.core.loads.pull`), or None."""
        return self.loads.get(Pull.name)

    @property
    def wrench(self) -> AppliedWrench | None:
        """Return the wrench on a region (:mod:`~modal_spring_ros.core.loads.wrench`), or None."""
        return self.loads.get(AppliedWrench.name)

    def start_pull(self, pull: Pull | None) -> None:
        """Pull a particle from now on (None: stop pulling). A reset ends it too."""
        self.set_load(Pull.name, pull)

    def start_wrench(self, wrench: AppliedWrench | None) -> None:
        """Push a region with a wrench from now on (None: stop). A reset ends it too."""
        self.set_load(AppliedWrench.name, wrench)

    def move_colliders(self, frame: str, pose: Pose) -> int:
        """
        Put the colliders attached to ``frame`` where ``pose`` says; return how many.

        They stay there through a reset (:meth:`~ContactLoad.placed_as`) until moved again.
        """
        contact = self.loads.get(ContactLoad.name)
        if contact is None:
            return 0
        self.set_load(ContactLoad.name, contact.moved(frame, pose))
        return sum(f == frame for f in contact.contact.frames)

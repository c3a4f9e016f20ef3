"""
A run that holds its loads: one per name, replaced whole, cleared by a reset, handed over whole.

Every simulation is a :class:`LoadHolder` (:mod:`~modal_spring_ros.core.simulations.base`):
its steps add the forces of :attr:`LoadHolder.loads` through the seat
(:mod:`~modal_spring_ros.core.loads.applied`), its reset clears them, and a run that takes over
from another (a settings change, a watch's shadow runs) takes every one of them.
"""
from __future__ import annotations

from modal_spring_ros.core.loads.added_colliders import AddedContact, placed, removed
from modal_spring_ros.core.loads.base import Load
from modal_spring_ros.core.loads.contact import ContactLoad, penalty
from modal_spring_ros.core.loads.grasp import closed_on, Grasp, GraspError
from modal_spring_ros.core.loads.pull import Pull
from modal_spring_ros.core.loads.wrench import AppliedWrench
from modal_spring_ros.core.model.colliders import Collider, Pose


class LoadHolder:
    """The loads a run holds, by name (:class:`~modal_spring_ros.core.loads.base.Load`)."""

    #: what acts on the particles from outside the scene, by name (a new dict on every change,
    #: so that a copy handed over is never changed under its holder)
    loads: dict[str, Load] = {}
    #: where the frames colliders and grippers are on were last said to be (kept by a reset
    #: and handed over, as the world is)
    frame_poses: dict[str, Pose] = {}

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

    def move_frame(self, frame: str, pose: Pose) -> int:
        """
        Tell the run where ``frame`` is; return how many colliders and grippers it moved.

        The colliders attached to it go there (and stay through a reset:
        :meth:`~ContactLoad.placed_as`), a gripper closed on it carries what it holds, and a
        gripper closing on it later closes there (:meth:`close_gripper`).
        """
        self.frame_poses = {**self.frame_poses, frame: pose}
        moved = 0
        contact = self.loads.get(ContactLoad.name)
        if contact is not None:
            self.set_load(ContactLoad.name, contact.moved(frame, pose))
            moved += sum(f == frame for f in contact.contact.frames)
        grasp = self.loads.get(Grasp.name)
        if grasp is not None and grasp.held(frame):
            self.set_load(Grasp.name, grasp.moved(frame, pose))
            moved += 1
        return moved

    def close_gripper(self, frame: str, reach: float) -> int:
        """
        Close the gripper on ``frame``: hold the free particles within ``reach`` of it.

        Return how many it holds. A reset opens every gripper.

        :raises GraspError: the frame's pose is not known yet, or nothing is within reach.
        """
        pose = self.frame_poses.get(frame)
        if pose is None:
            raise GraspError(f'{frame} has no pose yet (TF or frame_pose has not said where '
                             'it is)')
        stiffness, damping = penalty(self.model, self.dt, self.penalty_limit(), hold=True)
        grasp = closed_on(self.loads.get(Grasp.name), self.model, self.positions(), frame,
                          pose, reach, stiffness, damping, self.dt)
        self.set_load(Grasp.name, grasp)
        return grasp.held(frame)

    def open_gripper(self, frame: str) -> int:
        """Open the gripper on ``frame``; return how many particles it let go."""
        grasp = self.loads.get(Grasp.name)
        if grasp is None or not grasp.held(frame):
            return 0
        let_go = grasp.held(frame)
        self.set_load(Grasp.name, grasp.opened(frame))
        return let_go

    def add_collider(self, key: str, collider: Collider, pose: Pose) -> int:
        """
        Touch ``collider`` (its shape at its own origin) on ``key`` where ``pose`` puts it.

        Placing a key again moves it (the same shape) or replaces it; a reset clears them
        (:mod:`~modal_spring_ros.core.loads.added_colliders`). Return how many are added.
        """
        added = placed(self.loads.get(AddedContact.name), self.model.scene.contact, self.model,
                       key, collider, pose, self.dt, self.penalty_limit())
        self.set_load(AddedContact.name, added)
        return len(added.keys)

    def remove_collider(self, key: str | None) -> int:
        """Stop touching the collider added on ``key`` (None: every one); return how many left."""
        added = removed(self.loads.get(AddedContact.name), key)
        self.set_load(AddedContact.name, added)
        return 0 if added is None else len(added.keys)

    def describe_contacts(self) -> str:
        """Return what touches and what is held, as text (``no colliders``: neither)."""
        said = [load.describe() for name, load in self.loads.items()
                if name in (ContactLoad.name, AddedContact.name, Grasp.name) and load.describe()]
        return '; '.join(said) or 'no colliders'

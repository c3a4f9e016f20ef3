"""
Colliders added while the run goes (a robot's world seen at run time: RViz markers, a planner).

Each added collider has a key (a marker's ``ns/id``), a shape at its own origin and a
:class:`~modal_spring_ros.core.model.colliders.Pose`: the run touches it as it touches the
scene's (:class:`AddedContact` is a :class:`~modal_spring_ros.core.loads.contact.ContactLoad`
of its own, with the scene's friction). Placing a key again with the same shape moves it (what
it holds by friction rides along); with another shape it is a new collider; removing it lets go.
A reset clears them, as it ends a pull: they came with the run, not with the scene.
"""
from __future__ import annotations

import dataclasses
from typing import ClassVar

from modal_spring_ros.core.loads.contact import contact_load, ContactLoad
from modal_spring_ros.core.model.colliders import Collider, Contact, Pose
import numpy as np


@dataclasses.dataclass(frozen=True, eq=False)
class AddedContact(ContactLoad):
    """Contact with the colliders added at run time, each on its key as its frame."""

    name: ClassVar[str] = 'added_colliders'

    @property
    def keys(self) -> tuple[str, ...]:
        return self.contact.frames

    def describe(self) -> str:
        return f'{len(self.keys)} added: {super().describe()}'


def placed(added: AddedContact | None, scene_contact: Contact | None, model, key: str,
           collider: Collider, pose: Pose, dt: float, stability_limit: float) -> AddedContact:
    """
    Return ``added`` (None: none yet) with ``collider`` on ``key`` where ``pose`` puts it.

    The same shape on a key already placed is moved, its stick points kept; the others keep
    theirs. Friction is the scene's (none without a ``contact`` field).
    """
    if added is not None and key in added.keys:
        c = added.keys.index(key)
        if added.contact.colliders[c].to_dict() == collider.to_dict():
            return added.moved(key, pose)
    kept = [] if added is None else [c for c, k in enumerate(added.keys) if k != key]
    colliders = tuple(added.contact.colliders[c] for c in kept) + (collider,)
    keys = tuple(added.keys[c] for c in kept) + (key,)
    poses = tuple(added.poses[c] for c in kept) + (pose,)
    return _rebuilt(added, kept, scene_contact, model, colliders, keys, poses, dt,
                    stability_limit)


def removed(added: AddedContact | None, key: str | None) -> AddedContact | None:
    """Return ``added`` without the collider on ``key`` (None: without any); None when empty."""
    if added is None or key is None or key not in added.keys:
        return None if key is None else added
    kept = [c for c, k in enumerate(added.keys) if k != key]
    if not kept:
        return None
    contact = dataclasses.replace(added.contact,
                                  colliders=tuple(added.contact.colliders[c] for c in kept),
                                  frames=tuple(added.keys[c] for c in kept))
    return dataclasses.replace(added, contact=contact, anchors=added.anchors[kept],
                               depths=added.depths[kept], slips=added.slips[kept],
                               poses=tuple(added.poses[c] for c in kept))


def _rebuilt(added, kept, scene_contact, model, colliders, keys, poses, dt,
             stability_limit) -> AddedContact:
    static, sliding = ((scene_contact.static_friction, scene_contact.sliding_friction)
                       if scene_contact is not None else (0.0, 0.0))
    fresh = contact_load(model, Contact(colliders, static, sliding, keys), dt, stability_limit)
    anchors, depths, slips = fresh.anchors, fresh.depths, fresh.slips
    if added is not None and kept:       # the colliders kept keep what they hold
        anchors[:len(kept)], depths[:len(kept)] = added.anchors[kept], added.depths[kept]
        slips[:len(kept)] = added.slips[kept]
    return AddedContact(fresh.contact, fresh.stiffness, fresh.damping, fresh.mass, fresh.dt,
                        np.asarray(anchors), np.asarray(depths), np.asarray(slips),
                        poses=tuple(poses))

"""
The TF tree the node hears: named frames and the rigid transforms between them.

tf2's Python buffer (``tf2_ros``) is not on PyPI, so the node keeps the little of it it needs:
each frame's latest transform to its parent (from ``/tf`` and ``/tf_static``), and the transform
between any two connected frames, composed along the tree through their common ancestor. A
lookup uses each link's latest transform (tf2's "latest available" lookup, time 0), which is what
a clamp following a gripper and an input stamped in a sensor's frame ask for; there is no
history to interpolate in.

Everything in a message is input: a transform with a non-finite value or a quaternion that is not
a unit one (beyond :data:`QUATERNION_TOLERANCE`, as the pose topic), a frame that is its own
parent, an empty name or a link that would close a loop is refused with the reason, and the tree
keeps at most :data:`MAX_FRAMES` frames, so a flood of names cannot grow it without bound.
"""
from __future__ import annotations

import dataclasses
import math

from modal_spring_ros.core.motion.clamp_follower import (quaternion_product,
                                                         QUATERNION_TOLERANCE,
                                                         rotation_matrix, rotation_vector)
import numpy as np

#: most frames the tree keeps (a robot has tens to hundreds)
MAX_FRAMES = 10_000


@dataclasses.dataclass(frozen=True)
class Transform:
    """``x_parent = R x_child + translation``, ``R`` the unit quaternion ``(x, y, z, w)``."""

    translation: np.ndarray
    rotation: np.ndarray

    @classmethod
    def identity(cls) -> 'Transform':
        return cls(np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))

    def rotate(self, vectors: np.ndarray) -> np.ndarray:
        """Turn (3,) or (n, 3) vectors by the rotation."""
        return np.asarray(vectors, dtype=float) @ self.matrix().T

    def apply(self, points: np.ndarray) -> np.ndarray:
        """Carry (3,) or (n, 3) points from the child frame to the parent frame."""
        return self.rotate(points) + self.translation

    def then(self, inner: 'Transform') -> 'Transform':
        """Return ``self o inner``: first ``inner`` (grandchild to child), then this one."""
        return Transform(self.apply(inner.translation),
                         quaternion_product(self.rotation, inner.rotation))

    def inverse(self) -> 'Transform':
        conjugate = self.rotation * np.array([-1.0, -1.0, -1.0, 1.0])
        inverse = Transform(np.zeros(3), conjugate)
        return Transform(-inverse.rotate(self.translation), conjugate)

    def matrix(self) -> np.ndarray:
        """Return the 3 x 3 rotation matrix."""
        return rotation_matrix(rotation_vector(self.rotation))


def quaternion_from_matrix(rotation: np.ndarray) -> np.ndarray:
    """Return the unit quaternion ``(x, y, z, w)`` of a 3 x 3 rotation matrix (w >= 0)."""
    m = np.asarray(rotation, dtype=float)
    # Shepperd: the largest of the four squared components is taken from the diagonal
    squares = np.array([1 + m[0, 0] - m[1, 1] - m[2, 2], 1 - m[0, 0] + m[1, 1] - m[2, 2],
                        1 - m[0, 0] - m[1, 1] + m[2, 2], 1 + np.trace(m)])
    k = int(np.argmax(squares))
    s = 2.0 * math.sqrt(max(float(squares[k]), 1e-300))
    if k == 3:
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, s / 4]
    elif k == 0:
        q = [s / 4, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s]
    elif k == 1:
        q = [(m[0, 1] + m[1, 0]) / s, s / 4, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s]
    else:
        q = [(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, s / 4, (m[1, 0] - m[0, 1]) / s]
    q = np.array(q)
    q /= np.linalg.norm(q)
    return -q if q[3] < 0 else q


class FrameTree:
    """Frames by name, each with its parent and its latest transform to it."""

    def __init__(self, max_frames: int = MAX_FRAMES):
        self._max_frames = int(max_frames)
        #: child -> (parent, transform child -> parent)
        self._links: dict[str, tuple[str, Transform]] = {}

    def __len__(self) -> int:
        return len(self._links)

    def set_link(self, parent: str, child: str, translation, rotation) -> str | None:
        """
        Take ``child``'s transform to ``parent``; return why it is refused, or None.

        ``translation`` (3,) and ``rotation`` (a quaternion ``(x, y, z, w)``) carry points of
        ``child`` into ``parent``, as ``geometry_msgs/TransformStamped`` does. A refused link
        changes nothing.
        """
        parent, child = parent.lstrip('/'), child.lstrip('/')
        translation = np.asarray(translation, dtype=float)
        rotation = np.asarray(rotation, dtype=float)
        if not parent or not child:
            return 'a transform with an empty frame name'
        if parent == child:
            return f"frame '{child}' cannot be its own parent"
        if not (np.isfinite(translation).all() and np.isfinite(rotation).all()):
            return f"non-finite transform from '{child}' to '{parent}'"
        if abs(float(np.linalg.norm(rotation)) - 1.0) > QUATERNION_TOLERANCE:
            return f"the rotation from '{child}' to '{parent}' is not a unit quaternion"
        if child not in self._links and len(self._links) >= self._max_frames:
            return f'more than {self._max_frames} frames: {child!r} not kept'
        if child in self._ancestors(parent):
            return f"'{child}' -> '{parent}' would close a loop in the tree"
        self._links[child] = (parent, Transform(translation.copy(),
                                                rotation / np.linalg.norm(rotation)))
        return None

    def _ancestors(self, frame: str) -> list[str]:
        """``frame`` and its ancestors, nearest first (the tree has no loops)."""
        chain = [frame]
        while chain[-1] in self._links:
            chain.append(self._links[chain[-1]][0])
        return chain

    def _to_root(self, chain: list[str]) -> list[Transform]:
        """Transform of each frame of ``chain`` to the chain's last frame."""
        out = [Transform.identity()] * len(chain)
        for i in range(len(chain) - 2, -1, -1):
            out[i] = out[i + 1].then(self._links[chain[i]][1])
        return out

    def lookup(self, target: str, source: str) -> Transform | str:
        """
        Return what carries points of ``source`` into ``target``, or why it cannot.

        Composed along the tree from each link's latest transform.
        """
        target, source = target.lstrip('/'), source.lstrip('/')
        if target == source:
            return Transform.identity()
        up, down = self._ancestors(source), self._ancestors(target)
        common = next((frame for frame in up if frame in set(down)), None)
        if common is None:
            known = [f for f in (source, target) if f not in self._links and
                     not any(parent == f for parent, _ in self._links.values())]
            if known:
                return f"frame '{known[0]}' is not in the TF tree"
            return f"'{source}' and '{target}' are not connected in the TF tree"
        up, down = up[:up.index(common) + 1], down[:down.index(common) + 1]
        source_to_common = self._to_root(up)[0]
        target_to_common = self._to_root(down)[0]
        return target_to_common.inverse().then(source_to_common)

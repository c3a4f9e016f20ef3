"""
TF for the node: the frames it broadcasts, and the tree it hears.

:class:`FrameBroadcaster` publishes, with each frame of the stream and the same stamp, the
object's frame (the rigid motion the clamp gives the object: its rest shape, moved) and the
clamp's frame (at the centre of the fixed particles, turned with the clamp) under the node's
``frame_id`` on ``/tf``, so RViz, a robot's planners and ``tf2_echo`` place the object in the
robot's world. :class:`TfListener` keeps the transforms it hears on ``/tf`` and ``/tf_static`` in
a :class:`~modal_spring_ros.ros.frames.frame_tree.FrameTree`: inputs stamped in another frame are
carried into the node's frame through it, and with ``anchor.source`` tf the clamp follows a frame
of it.

``tf2_msgs`` (``/tf``'s message) is not among the ROS wheels on PyPI; the bootstrap generates it
(``.ci/interfaces``), a ROS install has it. Without it the node runs without TF and says so once.
"""
from __future__ import annotations

import threading
from typing import Callable

from geometry_msgs.msg import Quaternion, Transform as TransformFields, TransformStamped, Vector3
from modal_spring_ros.ros.frames.frame_tree import FrameTree, quaternion_from_matrix, Transform
import numpy as np
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Header

try:
    from tf2_msgs.msg import TFMessage
except ImportError:      # ROS from PyPI wheels without the bootstrap's generated tf2_msgs
    TFMessage = None

#: why TF is off, when it is
TF_MISSING = ('tf2_msgs is not installed (ROS from PyPI wheels lacks it: .ci/bootstrap '
              'generates it; a ROS install has it): TF is off')
#: QoS of /tf and /tf_static, as tf2_ros's broadcasters and listeners use them
TF_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
TF_STATIC_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE,
                           durability=DurabilityPolicy.TRANSIENT_LOCAL)


def tf_available() -> bool:
    return TFMessage is not None


def transform_message(parent: str, child: str, transform: Transform, stamp) -> TransformStamped:
    t, q = transform.translation.tolist(), transform.rotation.tolist()
    fields = TransformFields(translation=Vector3(x=t[0], y=t[1], z=t[2]),
                             rotation=Quaternion(x=q[0], y=q[1], z=q[2], w=q[3]))
    return TransformStamped(header=Header(stamp=stamp, frame_id=parent), child_frame_id=child,
                            transform=fields)


class FrameBroadcaster:
    """Publishes the object's and the clamp's frames under ``parent`` on ``/tf``."""

    def __init__(self, node, parent: str, object_frame: str, clamp_frame: str,
                 clamp_centre: np.ndarray | None):
        """``clamp_centre``: (3,) centre of the fixed particles at rest (None: no clamp)."""
        self._parent = parent
        self._object = object_frame
        self._clamp = clamp_frame
        self._centre = None if clamp_centre is None else np.asarray(clamp_centre, dtype=float)
        self._publisher = node.create_publisher(TFMessage, '/tf', TF_QOS)

    def publish(self, rotation: np.ndarray, translation: np.ndarray, stamp) -> None:
        """Publish the frames of the clamp's rigid motion ``x = R X + b`` (3D) at ``stamp``."""
        q = quaternion_from_matrix(rotation)
        frames = [transform_message(self._parent, self._object,
                                    Transform(np.asarray(translation, dtype=float), q), stamp)]
        if self._centre is not None:
            origin = rotation @ self._centre + translation
            frames.append(transform_message(self._parent, self._clamp, Transform(origin, q),
                                            stamp))
        self._publisher.publish(TFMessage(transforms=frames))


class TfListener:
    """The TF tree from ``/tf`` and ``/tf_static``; ``on_update`` is called after each message."""

    def __init__(self, node, on_update: Callable[[], None] | None = None):
        self.tree = FrameTree()
        self._lock = threading.Lock()
        self._on_update = on_update
        #: transforms refused (non-finite, not a unit quaternion, a loop, too many frames)
        self.refused = 0
        self.last_refusal = ''
        node.create_subscription(TFMessage, '/tf', self._take, TF_QOS)
        node.create_subscription(TFMessage, '/tf_static', self._take, TF_STATIC_QOS)

    def _take(self, message) -> None:
        with self._lock:
            for item in message.transforms:
                t, q = item.transform.translation, item.transform.rotation
                why = self.tree.set_link(item.header.frame_id, item.child_frame_id,
                                         (t.x, t.y, t.z), (q.x, q.y, q.z, q.w))
                if why is not None:
                    self.refused += 1
                    self.last_refusal = why
        if self._on_update is not None:
            self._on_update()

    def lookup(self, target: str, source: str) -> Transform | str:
        """Return what carries ``source``'s points into ``target`` (latest), or why it cannot."""
        with self._lock:
            return self.tree.lookup(target, source)

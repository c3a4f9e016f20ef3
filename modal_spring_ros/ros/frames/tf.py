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

Where ``tf2_ros`` imports (a ROS install; it is not on PyPI), the transforms the listener takes
are also kept in tf2's own ``Buffer`` and looked up there: the same answers as every other
tf2 user's (its frame rules, its latest-common-time lookups), tf2's reasons when a lookup fails.
The project's own tree still judges every transform first (non-finite, not a unit quaternion, a
loop, too many frames: refused and counted, never handed on) and answers without tf2.
"""
from __future__ import annotations

import threading
from typing import Callable

from geometry_msgs.msg import Quaternion, Transform as TransformFields, TransformStamped, Vector3
from modal_spring_ros.ros.frames.frame_tree import FrameTree, quaternion_from_matrix, Transform
import numpy as np
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.time import Time
from std_msgs.msg import Header

try:
    from tf2_msgs.msg import TFMessage
except ImportError:      # ROS from PyPI wheels without the bootstrap's generated tf2_msgs
    TFMessage = None
try:
    import tf2_ros
except ImportError:      # not among the ROS wheels on PyPI: the project's own tree answers
    tf2_ros = None

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
    """
    The TF tree from ``/tf`` and ``/tf_static``; ``on_update`` is called after each message.

    ``tf2``: the ``tf2_ros`` module to keep a ``Buffer`` of (by default the one that imports;
    None: the project's tree alone).
    """

    #: the authority tf2 records for the transforms this listener hands it
    AUTHORITY = 'modal_spring_ros'

    def __init__(self, node, on_update: Callable[[], None] | None = None, tf2=tf2_ros):
        self.tree = FrameTree()
        self._lock = threading.Lock()
        self._on_update = on_update
        self._tf2 = tf2
        #: tf2's own buffer, where tf2_ros imports (None: the project's tree answers)
        self.buffer = tf2.Buffer() if tf2 is not None else None
        #: transforms refused (non-finite, not a unit quaternion, a loop, too many frames)
        self.refused = 0
        self.last_refusal = ''
        node.create_subscription(TFMessage, '/tf', lambda m: self._take(m, False), TF_QOS)
        node.create_subscription(TFMessage, '/tf_static', lambda m: self._take(m, True),
                                 TF_STATIC_QOS)

    def _take(self, message, static: bool = False) -> None:
        with self._lock:
            for item in message.transforms:
                t, q = item.transform.translation, item.transform.rotation
                why = self.tree.set_link(item.header.frame_id, item.child_frame_id,
                                         (t.x, t.y, t.z), (q.x, q.y, q.z, q.w))
                if why is not None:
                    self.refused += 1
                    self.last_refusal = why
                elif self.buffer is not None:
                    self._hand_to_tf2(item, static)
        if self._on_update is not None:
            self._on_update()

    def _hand_to_tf2(self, item, static: bool) -> None:
        try:
            if static:
                self.buffer.set_transform_static(item, self.AUTHORITY)
            else:
                self.buffer.set_transform(item, self.AUTHORITY)
        except self._tf2.TransformException as error:    # tf2's own refusal: counted too
            self.refused += 1
            self.last_refusal = f'tf2: {error}'

    def lookup(self, target: str, source: str) -> Transform | str:
        """Return what carries ``source``'s points into ``target`` (latest), or why it cannot."""
        with self._lock:
            if self.buffer is None:
                return self.tree.lookup(target, source)
            try:
                found = self.buffer.lookup_transform(target, source, Time())
            except self._tf2.TransformException as error:
                return f'tf2 cannot carry {source} into {target}: {error}'
        t, q = found.transform.translation, found.transform.rotation
        return Transform(np.array([t.x, t.y, t.z]), np.array([q.x, q.y, q.z, q.w]))

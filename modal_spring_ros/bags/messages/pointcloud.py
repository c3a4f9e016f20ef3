"""
numpy <-> ``sensor_msgs/PointCloud2`` for particle clouds, without a per-point Python loop.

Layout (little-endian, ``height`` 1, one point per particle in scene order): ``x``, ``y``,
``z`` float32 at offsets 0, 4, 8 and ``displacement`` float32 at 12 (distance from the rest
position, for colouring in RViz or Foxglove); ``point_step`` 16, ``is_dense`` true.
"""
from __future__ import annotations

import array
import math

import numpy as np
try:     # making clouds needs ROS's message classes; reading them (xyz) does not
    from sensor_msgs.msg import PointCloud2, PointField
    from std_msgs.msg import Header
except ImportError:
    PointCloud2 = PointField = Header = None

FIELD_NAMES = ('x', 'y', 'z', 'displacement')
POINT_DTYPE = np.dtype({'names': list(FIELD_NAMES), 'formats': ['<f4'] * 4,
                        'offsets': [0, 4, 8, 12], 'itemsize': 16})
_FIELDS = [PointField(name=name, offset=4 * k, datatype=PointField.FLOAT32, count=1)
           for k, name in enumerate(FIELD_NAMES)] if PointField is not None else []


def distance_from_rest(positions: np.ndarray, rest_positions: np.ndarray) -> np.ndarray:
    """(n,) Euclidean distance of each point from its rest position."""
    moved = positions - rest_positions
    distance = np.einsum('ij,ij->i', moved, moved)  # a quarter of np.linalg.norm's time
    return np.sqrt(distance, out=distance)


def to_pointcloud2(positions: np.ndarray, rest_positions: np.ndarray, header: Header
                   ) -> PointCloud2:
    """Return a cloud of ``positions`` (n, 3), each point's displacement from rest beside it."""
    cloud = CloudBuffer(rest_positions)
    cloud.write(positions)
    return cloud.message(header)


class CloudBuffer:
    """
    One cloud's bytes, written in place frame after frame: no array or copy per frame.

    A frame is written either from positions (:meth:`write`) or, cheaper, from each particle's
    movement from its rest position, axis by axis: a run writes it into :attr:`movement` (a
    (3, n) float32 array), then :meth:`write_movement` adds it to the rest positions column by
    column. Either way the displacement column follows from the movement, :attr:`points` (an
    (n, 4) float32 view of the bytes: ``x``, ``y``, ``z``, ``displacement``) holds the frame
    and :meth:`message` returns a cloud whose ``data`` is those bytes. The next frame writes over
    them, so publish (or serialise) a message before the next one is written.
    """

    def __init__(self, rest_positions: np.ndarray):
        n = rest_positions.shape[0]
        self._bytes = array.array('B', bytes(16 * n))  # what rclpy takes as uint8[] as it is
        self.points = np.frombuffer(self._bytes, dtype='<f4').reshape(n, 4)
        #: each particle's movement from rest, axis by axis: (3, n) float32, C-contiguous
        self.movement = np.zeros((3, n), dtype=np.float32)
        # axis by axis as well: every pass below runs over contiguous rows (numpy's loops over
        # rows of three or four values are several times slower)
        self._rest = np.array(rest_positions.T, dtype=np.float32, order='C')
        self._distance = np.zeros(n, dtype=np.float32)

    def write(self, positions: np.ndarray) -> None:
        """Write a frame of ``positions`` (n, 3), as they are in float32."""
        self.points[:, :3] = positions
        np.subtract(positions.T, self._rest, out=self.movement)
        self._write_distance()

    def write_run(self, run) -> None:
        """Write a frame of a run: its particles' movement (``run.movement_into``), then it."""
        run.movement_into(self.movement)
        self.write_movement()

    def write_movement(self) -> None:
        """Write a frame of the rest positions plus :attr:`movement`."""
        for axis in range(3):
            np.add(self._rest[axis], self.movement[axis], out=self.points[:, axis])
        self._write_distance()

    def _write_distance(self) -> None:
        np.einsum('ij,ij->j', self.movement, self.movement, out=self._distance)
        np.sqrt(self._distance, out=self._distance)
        self.points[:, 3] = self._distance

    def finite(self) -> bool:
        """
        Tell whether the frame written is finite: one pass over its displacements.

        A point off the float32 range, or not finite, has a displacement that is not finite.
        """
        return math.isfinite(float(np.add.reduce(self._distance, dtype=np.float64)))

    def message(self, header: Header) -> PointCloud2:
        """Return the cloud of the frame written."""
        n = self.points.shape[0]
        msg = PointCloud2(check_fields=True, header=header, height=1, width=n, fields=_FIELDS,
                          is_bigendian=False, point_step=16, row_step=16 * n, is_dense=True)
        # with its fields checked, the setter takes a uint8 array.array as it is (unchecked, or
        # in the constructor, it copies it): the bytes written are the bytes published
        msg.data = self._bytes
        return msg


def from_pointcloud2(msg) -> np.ndarray:
    """
    Structured array (fields x, y, z, displacement) from a cloud in this layout.

    Accepts any PointCloud2-like object (rclpy, mcap_ros2 or rosbags decoded). Raises
    ValueError when the layout is not the one above.
    """
    names = [f.name for f in msg.fields]
    offsets = [f.offset for f in msg.fields]
    if names[:4] != list(FIELD_NAMES) or offsets[:4] != [0, 4, 8, 12] or msg.point_step < 16:
        raise ValueError(f'unexpected PointCloud2 layout: fields {names} at {offsets}')
    if msg.is_bigendian:
        raise ValueError('big-endian PointCloud2 is not supported')
    raw = np.frombuffer(bytes(msg.data), dtype=np.uint8)
    count = msg.width * msg.height
    dtype = np.dtype({'names': list(FIELD_NAMES), 'formats': ['<f4'] * 4,
                      'offsets': [0, 4, 8, 12], 'itemsize': msg.point_step})
    return np.frombuffer(raw.tobytes(), dtype=dtype, count=count)


def xyz(msg) -> np.ndarray:
    """(n, 3) float64 positions from a cloud in this layout."""
    cloud = from_pointcloud2(msg)
    return np.stack([cloud['x'], cloud['y'], cloud['z']], axis=1).astype(np.float64)

"""
numpy <-> ``sensor_msgs/PointCloud2`` for particle clouds, without a per-point Python loop.

Layout (little-endian, ``height`` 1, one point per particle in scene order): ``x``, ``y``,
``z`` float32 at offsets 0, 4, 8 and ``displacement`` float32 at 12 (distance from the rest
position, for colouring in RViz or Foxglove); ``point_step`` 16, ``is_dense`` true.
"""
from __future__ import annotations

import numpy as np
from sensor_msgs.msg import PointCloud2, PointField
from std_msgs.msg import Header

FIELD_NAMES = ('x', 'y', 'z', 'displacement')
POINT_DTYPE = np.dtype({'names': list(FIELD_NAMES), 'formats': ['<f4'] * 4,
                        'offsets': [0, 4, 8, 12], 'itemsize': 16})
_FIELDS = [PointField(name=name, offset=4 * k, datatype=PointField.FLOAT32, count=1)
           for k, name in enumerate(FIELD_NAMES)]


def distance_from_rest(positions: np.ndarray, rest_positions: np.ndarray) -> np.ndarray:
    """(n,) Euclidean distance of each point from its rest position."""
    moved = positions - rest_positions
    distance = np.einsum('ij,ij->i', moved, moved)  # a quarter of np.linalg.norm's time
    return np.sqrt(distance, out=distance)


def to_pointcloud2(positions: np.ndarray, rest_positions: np.ndarray, header: Header
                   ) -> PointCloud2:
    """Return a cloud of ``positions`` (n, 3), each point's displacement from rest beside it."""
    n = positions.shape[0]
    buf = np.empty((n, 4), dtype='<f4')
    buf[:, :3] = positions
    buf[:, 3] = distance_from_rest(positions, rest_positions)
    msg = PointCloud2()
    msg.header = header
    msg.height = 1
    msg.width = n
    msg.fields = _FIELDS
    msg.is_bigendian = False
    msg.point_step = 16
    msg.row_step = 16 * n
    msg.is_dense = True
    msg.data = buf.tobytes()
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

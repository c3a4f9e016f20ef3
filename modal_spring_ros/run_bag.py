"""Lossless capture: a simulation run written straight to a rosbag2 MCAP bag, every frame,
without going through DDS; and the description needed to re-run it.

Frames go to ``/points`` as PointCloud2 (stamped with simulation time, which is also the log
and publish time). A ``modal_spring_ros`` metadata record holds the scene (full definition),
the simulation settings, the frame spacing and the duration.
"""
from __future__ import annotations

import numpy as np

from modal_spring_ros.bag_qos import profiles_to_yaml
from modal_spring_ros.bag_writer import BagWriter
from modal_spring_ros.simulation_factory import SimulationConfig

POINTS_TOPIC = "/points"


def points_qos_yaml() -> str:
    """The QoS the node offers on ``points`` (reliable, volatile, keep last 10)."""
    from rclpy.qos import QoSProfile
    return profiles_to_yaml([QoSProfile(depth=10)])


class RunBagWriter:
    """Frames of one run into a new bag; call :meth:`frame` per frame, then :meth:`close`."""

    def __init__(self, directory, scene, config: SimulationConfig, *, dt: float,
                 frame_every: int, duration: float, frame_id: str = "world",
                 source: str = "modal_spring_sim"):
        self.scene = scene
        self.frame_id = frame_id
        self.writer = BagWriter(directory)
        self.writer.add_topic(POINTS_TOPIC, "sensor_msgs/msg/PointCloud2", points_qos_yaml())
        self.writer.add_run_record({
            "source": source, "scene_yaml": scene.to_yaml(), "config": config.to_dict(),
            "dt": dt, "frame_every": frame_every, "duration": duration, "frame_id": frame_id})

    def frame(self, t: float, positions: np.ndarray) -> None:
        from std_msgs.msg import Header

        from modal_spring_ros.pointcloud import to_pointcloud2
        from modal_spring_ros.ros_time import to_nanoseconds, to_time_msg
        stamp = to_time_msg(t)
        msg = to_pointcloud2(positions, self.scene.rest_positions,
                             Header(stamp=stamp, frame_id=self.frame_id))
        ns = to_nanoseconds(stamp)
        self.writer.write_message(POINTS_TOPIC, msg, ns, ns)

    def close(self) -> None:
        self.writer.close()

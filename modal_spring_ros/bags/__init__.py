"""
rosbag2 bags in MCAP storage.

Message definitions and their CDR encoding, QoS, writer, reader, the lossless capture of a run,
and the reference bags. Also the messages they hold (point clouds, stamps).

Imports from ``core``, ``scenes`` and ``runs``. Reading needs no ROS (messages are decoded from
the bags' own definitions); writing uses the ROS message classes and rclpy's QoS.
"""

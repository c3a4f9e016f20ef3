"""
rosbag2 bags in MCAP storage.

Message definitions, QoS, writer, reader, the lossless capture of a run, and the reference bags.
Also the messages they hold (point clouds, stamps).

Imports from ``core``, ``scenes`` and ``runs``; uses rclpy only to (de)serialise messages.
"""

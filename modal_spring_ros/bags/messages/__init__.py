"""
What a bag holds, message by message: definitions, their CDR encoding, QoS, clouds and stamps.

``message_types`` checks a type name (never a module to import); ``message_definitions`` finds
a type's ``.msg`` text and hash as rosbag2 stores them; ``cdr_encoder`` encodes a message from
that text; ``qos`` writes and reads offered QoS profiles; ``pointcloud`` and ``stamps`` are the
point clouds and times a run's frames carry. A new kind of message a bag keeps goes here.
"""

"""
What the node takes from the graph.

Every input declared once (``input_kinds``: topic, type, checks, effect, the topic a capture
keeps it under), subscribed (``subscriptions``) on a companion node spun in its own paced
thread (``input_node``); what the robot's world inputs do (frames, grippers, marker colliders)
is in ``robot_world``. A new input is one entry of ``input_kinds.INPUTS``.
"""

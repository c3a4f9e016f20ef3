"""
The ROS tools beside the node.

``recorder`` (topics into a rosbag2 MCAP bag), ``player`` (a bag played back on its topics),
``resimulate`` (a recorded run re-run into a new bag) and ``live_view`` (the graph's stream on
a Foxglove WebSocket server). A tool is a module here and a console script in ``cli``.
"""

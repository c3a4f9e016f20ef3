"""
What a ROS process needs to start and stop cleanly, whatever it runs.

``pooled_executor`` (callbacks on a pool of threads; a stop lets those handed over finish),
``stop_signals`` (Ctrl-C and SIGTERM as a request to stop), ``shared_memory`` (Fast DDS's
segment chosen before the middleware starts, for large clouds), ``namesakes`` (other nodes of
the same name), ``companion_node`` (a node a tool starts, ended with the tool however it
ends), ``interpreter_switching`` (a busy thread never starves the stream of the
interpreter). A module here imports no other ROS room: add one that any node or tool could use
as it is.
"""

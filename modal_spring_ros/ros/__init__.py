"""
The ROS layer: the node and the tools that speak ROS, in rooms by concept.

At the top, the node (``node``: wiring only), the same node as a lifecycle node
(``managed_node``) and its parameters' declarations (``parameters``). The rooms, lowest first
(a room imports only from the rooms before it and from ``parameters``; the architecture test
checks it):

* ``process``: what a ROS process needs to start and stop cleanly (the executor, the stop
  signals, the middleware's shared memory, other nodes of the same name).
* ``frames``: TF, heard and broadcast.
* ``changes``: parameter requests turned into typed state changes for the simulation thread.
* ``inputs``: the node's subscriptions, every input declared once.
* ``stream``: the simulation thread and what it publishes, paces, reports and watches.
* ``tools``: the ROS tools beside the node (record, replay, re-simulate, the live view).

A new concept gets a room of its own (a subpackage whose docstring says what it holds and how
to add to it); a module goes in the room of the concept it serves.
"""

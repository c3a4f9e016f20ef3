"""
Parameter requests turned into state changes.

``node_parameters`` validates a request on set and commits it after; ``change_preparer`` does
the slow part off the services' thread; ``parameter_changes`` turns a request into a typed
request (``requests``: the only way a change reaches the simulation thread). A new kind of
change is a request class in ``requests`` and its planning in ``parameter_changes``.
"""

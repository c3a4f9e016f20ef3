"""
The numerical core: scene data, forces, bases, integrators, the filter band, simulations.

Grouped in rooms: ``model`` (a scene's data, stiffness, the model), ``motion`` (the clamp and
what its motion loads), ``bases`` (rest modes, derivatives, the choice of modes), ``forces``
(force models: a contract and a registry), ``integrators``, ``simulations``, ``auto`` (the
automatic choice's pilot run and work model); the filter band, the run's configuration, the
factory that builds a run and the worker process stay at the top.

Pure Python, numpy and scipy: nothing here imports ROS, MCAP or matplotlib, so the method is
used and tested on its own. Lower than every other layer; imports nothing from them.
"""

"""
The numerical core: scene data, forces, bases, integrators, the filter band, simulations.

Pure Python, numpy and scipy: nothing here imports ROS, MCAP or matplotlib, so the method is
used and tested on its own. Lower than every other layer; imports nothing from them.
"""

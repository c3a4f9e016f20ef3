"""
The ROS layer.

The node (wiring), its parameters, diagnostics, simulation thread, outputs, the recorder and the
re-simulation of recorded node runs. Imports every lower layer.
"""

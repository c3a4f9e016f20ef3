"""
What things cost, as suites.

A step and a frame (``steps``), the live stream beside busy processes (``stream``,
``busy_load``, ``process_cpu``), memory and set-up as a scene grows (``memory``), a user's mesh
from file to stream (``meshes``).
"""

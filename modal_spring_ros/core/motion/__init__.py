"""
How the clamp moves and what its motion loads the object with.

A prescribed base motion (translation, turning), a rigid frame, the inertial loads of a turning
frame, and a clamp following poses. What acts on the particles from outside is in
:mod:`~modal_spring_ros.core.loads`.
"""

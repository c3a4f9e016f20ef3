"""
How the clamp moves and what its motion loads the object with.

A prescribed base motion (translation, turning), a rigid frame, the inertial loads of a turning
frame, a clamp following poses, and a particle pulled toward a point.
"""

"""
Loads: what acts on the particles from outside the scene, held by the run.

A contract (:class:`~modal_spring_ros.core.loads.base.Load`: forces on free DOFs in the world's
directions, from the particles' world positions, while it lasts), one load a module (``pull``:
a particle pulled toward a point; ``wrench``: a force and torque spread over a region;
``contact``: the scene's colliders; ``added_colliders``: colliders added at run time;
``grasp``: grippers holding particles), and the seat every method steps them through
(``applied``: each load's forces turned into the frame the method steps in). A run holds one
load per name (:meth:`~modal_spring_ros.core.simulations.base.Simulation.set_load`); a reset
clears them, a hand-over (a settings change, a watch's shadow runs) takes them all. A new load
is one module here with a ``Load`` subclass, and, for one a ROS message brings, one entry of
``ros/inputs/input_kinds.py``.
"""

"""
modal_spring_ros: stream physically based, frequency-filtered mass-spring deformations.

The numerical core (scene, forces, stiffness, modes, integrators, filter, simulation) has no
ROS dependency; the ROS node, recorder and player are thin layers over it.
"""
__version__ = '0.1.0'

"""
What RViz draws besides the cloud: the object's surface and the scene's colliders.

``mesh_marker`` turns a frame into the object's surface (or springs) coloured by displacement;
``collider_markers`` turns the scene's colliders into RViz primitives. Pure functions of plain
values and messages: the stream (``ros/stream/outputs``) publishes them. A new drawing goes here.
"""

"""
Scenes: scene files read into :class:`~modal_spring_ros.core.model.scene.Scene` objects, and back.

At the top, ``schema`` (a scene's YAML, or the mapping it parses to, checked into a Scene),
``resources`` (the built-in scenes shipped in ``config/``, the package's data folder),
``ament_index`` (a package's folders, with or without ROS), ``lattice`` and ``sized`` (sheets
and blocks of any size) and ``generator`` (random scenes). The rooms:

* ``fields``: each field of a scene file read, every refusal naming it (``reader``: typed
  reading; ``limits``: the bounds; ``fixed_regions``, ``mesh_fields``, ``bending_fields``).
* ``meshes``: mesh files made mass-spring networks (``mesh_files``: reading them with trimesh
  and meshio; ``mesh_network``; ``inside``: which points a closed surface encloses).
* ``files``: scenes as files (``yaml_reading`` within bounds, ``writing``, ``scene_archive``
  (what bags and runs keep), ``declared_size`` (a file's particles, read without building it)).

A new field is a module in ``fields`` read by ``schema``. Imports only from ``core``.
"""

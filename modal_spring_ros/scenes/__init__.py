"""
Scenes: the YAML schema, lattice generators, and the built-in scenes shipped in ``config/``.

Builds :class:`~modal_spring_ros.core.model.scene.Scene` objects; imports only from ``core``.
"""

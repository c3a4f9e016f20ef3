"""
How many particles a scene file declares, read without building the scene.

For choices made before a scene is loaded (the node's middleware transport is set up before the
node can read its parameters and load its scene): a lattice's counts, a list of positions, a
mesh file's vertices (a closed surface filled as a volume: about twice its vertices). Anything
that cannot be read cheaply, or is not valid, gives None: the scene's own loading then says
what is wrong with it.
"""
from __future__ import annotations

import math

from modal_spring_ros.scenes.files.yaml_reading import load_yaml, read_scene_text
from modal_spring_ros.scenes.meshes.mesh_files import read_mesh, resolve_mesh_path
from modal_spring_ros.scenes.resources import scene_file


def declared_particles(name_or_path: str) -> int | None:
    """Return the particles the scene declares, or None where that cannot be read cheaply."""
    try:
        path = scene_file(name_or_path)
        data = load_yaml(read_scene_text(path), str(path))
        if 'mesh' in data:
            spec = data['mesh']
            mesh = read_mesh(resolve_mesh_path(str(spec['file']), str(path)))
            filled = spec.get('kind') == 'volume' and not mesh.tetrahedra.size
            return len(mesh.vertices) * (2 if filled else 1)
        particles = data['particles']
        if 'lattice' in particles:
            return math.prod(int(c) for c in particles['lattice']['counts'])
        return len(particles['positions'])
    except Exception:  # noqa: BLE001  any failure: not known here; loading reports it
        return None

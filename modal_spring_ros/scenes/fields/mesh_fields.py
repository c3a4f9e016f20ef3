"""
A scene file's ``mesh`` and ``material`` fields: the particles and springs of a mesh scene.

```yaml
mesh: {file: flag.obj, kind: surface, scale: 0.01, rotation_deg: [90, 0, 0],
       translation: [0, 0, 1]}
material: {density: 0.2, stiffness: 400.0, bending: 0.05}
```

``file``: relative to the scene file, absolute, or ``package://pkg/path``. ``kind``: ``surface``
(cloth, shells; density kg/m^2, stiffness N/m) or ``volume`` (solids; kg/m^3, Pa). The mesh is
scaled (one factor, or one per axis), turned (x, then y, then z, about the world axes, degrees) and
moved, in that order. See :mod:`~modal_spring_ros.scenes.meshes.mesh_network` for what is built.
"""
from __future__ import annotations

import math
from typing import Any, Callable

from modal_spring_ros.core.model.scene import SceneError
from modal_spring_ros.scenes.fields.limits import LIMITS
from modal_spring_ros.scenes.fields.reader import FieldReader, short
from modal_spring_ros.scenes.meshes.mesh_files import read_mesh, resolve_mesh_path
from modal_spring_ros.scenes.meshes.mesh_network import (Material, Network, surface_network,
                                                         volume_network)
import numpy as np

MESH_KEYS = ('file', 'kind', 'scale', 'rotation_deg', 'translation')
MATERIAL_KEYS = ('density', 'stiffness', 'bending')
KINDS = {'surface': surface_network, 'volume': volume_network}


def mesh_network(reader: FieldReader, spec: Any, material: Any,
                 check_size: Callable[[int, str], None],
                 progress: Callable[[str], None] | None = None) -> Network:
    """
    Read ``mesh`` and ``material`` and build the network; ``check_size`` refuses a large one.

    ``progress`` hears of the stages (reading the file, building the springs).
    """
    spec = reader.mapping(spec, 'mesh')
    reader.known_keys(spec, 'mesh', MESH_KEYS)
    name = reader.required(spec, 'file', 'mesh')
    if not isinstance(name, str) or not name:
        raise reader.fail('mesh.file', f'must be a file name, got {short(name)}')
    kind = reader.choice(spec.get('kind', 'surface'), 'mesh.kind', KINDS)
    if material is None:
        raise reader.fail('material', 'missing: a mesh scene needs density and stiffness')
    properties = _material(reader, material)
    say = progress or (lambda line: None)
    try:
        path = resolve_mesh_path(name, reader.source)
        say(f'mesh {name}: reading')
        mesh = read_mesh(path)
    except SceneError as exc:
        raise reader.fail('mesh.file', str(exc)) from None
    if not (mesh.triangles.size or mesh.tetrahedra.size):
        raise reader.fail('mesh', f'mesh {name}: has no triangles (nor tetrahedra)')
    check_size(mesh.vertices.shape[0] * (2 if kind == 'volume' else 1), 'mesh.file')
    say(f'mesh {name}: {mesh.vertices.shape[0]:,} vertices, {mesh.triangles.shape[0]:,} '
        f'triangles, {mesh.tetrahedra.shape[0]:,} tetrahedra: building its {kind}')
    mesh = _placed(reader, spec, mesh)
    try:
        return KINDS[kind](mesh, properties, name)
    except SceneError as exc:
        raise reader.fail('mesh', str(exc)) from None


def _material(reader: FieldReader, spec: Any) -> Material:
    spec = reader.mapping(spec, 'material')
    reader.known_keys(spec, 'material', MATERIAL_KEYS)
    return Material(
        density=reader.number(reader.required(spec, 'density', 'material'), 'material.density',
                              positive=True, limit=LIMITS['mass']),
        stiffness=reader.number(reader.required(spec, 'stiffness', 'material'),
                                'material.stiffness', positive=True, limit=LIMITS['stiffness']),
        bending=reader.number(spec.get('bending', 0.0), 'material.bending', non_negative=True,
                              limit=1e3))


def _placed(reader: FieldReader, spec: Any, mesh):
    scale = spec.get('scale', 1.0)
    if isinstance(scale, (list, tuple)):
        if len(scale) != 3:
            raise reader.fail('mesh.scale', f'must be one number or three, got {short(scale)}')
        factors = np.array([reader.number(s, f'mesh.scale[{i}]', positive=True, limit=1e6)
                            for i, s in enumerate(scale)])
    else:
        factors = np.full(3, reader.number(scale, 'mesh.scale', positive=True, limit=1e6))
    angles = reader.vector3(spec.get('rotation_deg', [0.0, 0.0, 0.0]), 'mesh.rotation_deg',
                            LIMITS['amplitude_deg'])
    shift = reader.vector3(spec.get('translation', [0.0, 0.0, 0.0]), 'mesh.translation',
                           LIMITS['position'])
    x = (mesh.vertices * factors) @ _rotation(angles).T + shift
    if np.max(np.abs(x)) > LIMITS['position']:
        raise reader.fail('mesh', f'placed, the mesh reaches {np.max(np.abs(x)):.3g} m '
                          f"(at most {LIMITS['position']:g})")
    return type(mesh)(x, mesh.triangles, mesh.tetrahedra)


def _rotation(degrees: np.ndarray) -> np.ndarray:
    """Return the turn about x, then y, then z (world axes)."""
    out = np.eye(3)
    for axis, angle in enumerate(np.radians(degrees)):
        c, s = math.cos(angle), math.sin(angle)
        i, j = ((1, 2), (2, 0), (0, 1))[axis]  # cyclic: right-handed turns
        turn = np.eye(3)
        turn[i, i], turn[i, j], turn[j, i], turn[j, j] = c, -s, s, c
        out = turn @ out
    return out

"""
Sheets and blocks of a given size: the same object at any resolution.

For benchmarks and tests that follow how a run grows with its scene. The sheet is the built-in
sheets' object (0.9 m x 0.9 m, 1 kg, 1000 N/m springs, top row fixed and swaying slowly,
mass-proportional Rayleigh damping; in 2D its low modes do not depend on the resolution), the
block a 0.3 m cube of 1 kg clamped on one face.
"""
from __future__ import annotations

from modal_spring_ros.core.model.scene import Scene
from modal_spring_ros.scenes.schema import scene_from_dict

#: Kinds of sized scenes.
KINDS = ('sheet', 'block')


def sized_scene(kind: str, side: int) -> Scene:
    """Return a ``side`` x ``side`` sheet or a ``side``^3 block (``kind`` in :data:`KINDS`)."""
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {', '.join(KINDS)}, got {kind!r}")
    if side < 2:
        raise ValueError(f'side must be at least 2, got {side}')
    if kind == 'sheet':
        spacing = 0.9 / (side - 1)
        spec = {'dimension': 2, 'plane': 'xz',
                'particles': {'lattice': {'counts': [side, side], 'spacing': spacing,
                                          'origin': [0.0, 0.0, -0.9]},
                              'mass': 1.0 / side ** 2},
                'springs': {'connect': ['edges', 'diagonals'], 'stiffness': 1000.0},
                'fixed': {'face': '+z'},
                'damping': {'rayleigh': {'alpha': 1.2, 'beta': 0.0}},
                'anchor_motion': [{'axis': 'x', 'amplitude': 0.02, 'frequency_hz': 0.7,
                                   'ramp_s': 1.0}]}
    else:
        spacing = 0.3 / (side - 1)
        spec = {'dimension': 3,
                'particles': {'lattice': {'counts': [side, side, side], 'spacing': spacing,
                                          'origin': [0.0, 0.0, 0.0]},
                              'mass': 1.0 / side ** 3},
                'springs': {'connect': ['edges', 'diagonals'], 'stiffness': 1000.0},
                'fixed': {'face': '-x'},
                'damping': {'ratio': 0.02}}
    name = f'{kind}_{side}'
    spec.update(name=name, description=f'sized {kind}, {side} particles a side',
                gravity=[0.0, 0.0, -9.81], simulation={'duration': 5.0})
    return scene_from_dict(spec, source=name)

"""
A scene written out in the scene file format: every particle and spring listed.

What :func:`modal_spring_ros.scenes.schema.scene_from_dict` (and a scene file) loads back: runs
and bags keep the scene they ran as this text, so that a run can be re-simulated from its record
alone.
"""
from __future__ import annotations

from typing import Any

from modal_spring_ros.core.model.scene import Scene
import numpy as np
import yaml


def scene_to_dict(scene: Scene) -> dict[str, Any]:
    """
    Return the full explicit definition, every particle and spring listed.

    What :func:`modal_spring_ros.scenes.schema.scene_from_dict` loads back.
    """
    return {
        'name': scene.name,
        'description': scene.description,
        'dimension': scene.dimension,
        **({'axis': 'xyz'[scene.axes[0]]} if scene.dimension == 1 else {}),
        **({'plane': ''.join('xyz'[a] for a in scene.axes)} if scene.dimension == 2 else {}),
        # the shape as built: a scene about its loaded shape finds it again on load
        'reference': 'loaded' if scene.loaded else 'rest',
        'particles': {
            'positions': (scene.unloaded_positions if scene.loaded
                          else scene.rest_positions).tolist(),
            'mass': scene.mass.tolist(),
        },
        'springs': {
            'pairs': scene.springs.tolist(),
            'stiffness': scene.stiffness.tolist(),
        },
        **({'triangles': scene.triangles.tolist()} if scene.triangles is not None else {}),
        'fixed': {'indices': np.flatnonzero(scene.fixed).tolist()},
        'gravity': scene.gravity.tolist(),
        'damping': {
            'ratio': scene.damping.ratio,
            'rayleigh': {
                'alpha': scene.damping.rayleigh_alpha,
                'beta': scene.damping.rayleigh_beta,
            },
        },
        'anchor_motion': scene.anchor_motion.to_list(),
        'simulation': {'dt': scene.default_dt, 'duration': scene.default_duration},
    }


def scene_to_yaml(scene: Scene) -> str:
    """Return :func:`scene_to_dict` as YAML text (keys in the file format's order)."""
    return yaml.safe_dump(scene_to_dict(scene), sort_keys=False)

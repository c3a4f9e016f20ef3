"""
A scene written out in the scene file format: every particle and spring listed.

What :func:`modal_spring_ros.scenes.schema.scene_from_dict` (and a scene file) loads back. The
definition splits into its arrays and the rest (:func:`scene_arrays`, :func:`scene_header`):
runs and bags keep the scene they ran that way
(:mod:`~modal_spring_ros.scenes.files.scene_archive`), so that a run can be re-simulated from its
record alone, at any size.
"""
from __future__ import annotations

from typing import Any

from modal_spring_ros.core.laws import DEFAULT_LAW
from modal_spring_ros.core.model.scene import Scene
import numpy as np
import yaml

#: libyaml's safe dumper where PyYAML was built with it, else PyYAML's own (the same text)
DUMPER = getattr(yaml, 'CSafeDumper', yaml.SafeDumper)


#: where each of a scene's arrays sits in its definition: name -> (section or None, key)
ARRAY_PLACES = {'positions': ('particles', 'positions'), 'mass': ('particles', 'mass'),
                'pairs': ('springs', 'pairs'), 'stiffness': ('springs', 'stiffness'),
                'triangles': (None, 'triangles'), 'fixed': ('fixed', 'indices'),
                'hinges': ('bending', 'hinges'), 'hinge_weights': ('bending', 'weights')}


def scene_to_dict(scene: Scene) -> dict[str, Any]:
    """
    Return the full explicit definition, every particle and spring listed.

    What :func:`modal_spring_ros.scenes.schema.scene_from_dict` loads back.
    """
    return with_arrays(scene_header(scene),
                       {name: a.tolist() for name, a in scene_arrays(scene).items()})


def scene_arrays(scene: Scene) -> dict[str, np.ndarray]:
    """Return the scene's per-particle and per-spring arrays, by :data:`ARRAY_PLACES` name."""
    arrays = {
        # the shape as built: a scene about its loaded shape finds it again on load
        'positions': scene.unloaded_positions if scene.loaded else scene.rest_positions,
        'mass': scene.mass, 'pairs': scene.springs, 'stiffness': scene.stiffness,
        'fixed': np.flatnonzero(scene.fixed)}
    if scene.triangles is not None:
        arrays['triangles'] = scene.triangles
    if scene.bending is not None:
        arrays['hinges'] = scene.bending.hinges
        arrays['hinge_weights'] = scene.bending.weights
    return arrays


def scene_header(scene: Scene) -> dict[str, Any]:
    """Return the definition without its arrays (:func:`with_arrays` puts them back)."""
    return {
        'name': scene.name,
        'description': scene.description,
        'dimension': scene.dimension,
        **({'axis': 'xyz'[scene.axes[0]]} if scene.dimension == 1 else {}),
        **({'plane': ''.join('xyz'[a] for a in scene.axes)} if scene.dimension == 2 else {}),
        'reference': 'loaded' if scene.loaded else 'rest',
        'particles': {},
        'springs': {},
        'fixed': {},
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
        **({'contact': scene.contact.to_dict()} if scene.contact is not None else {}),
        **({'spring_law': scene.spring_law} if scene.spring_law != DEFAULT_LAW else {}),
    }


def with_arrays(header: dict[str, Any], arrays: dict[str, Any]) -> dict[str, Any]:
    """Return ``header`` (not changed) with ``arrays`` in their places (:data:`ARRAY_PLACES`)."""
    data = {key: dict(value) if isinstance(value, dict) else value
            for key, value in header.items()}
    for name, value in arrays.items():
        section, key = ARRAY_PLACES[name]
        if section is None:
            data[key] = value
        elif isinstance(data.get(section, {}), dict):
            data.setdefault(section, {})[key] = value
    return data


def scene_to_yaml(scene: Scene) -> str:
    """
    Return :func:`scene_to_dict` as YAML text (keys in the file format's order).

    With libyaml's safe dumper where PyYAML has it (a 100k-particle scene in a second or two,
    where PyYAML's own takes over ten: a node's capture writes its scene before streaming).
    """
    return yaml.dump(scene_to_dict(scene), Dumper=DUMPER, sort_keys=False)

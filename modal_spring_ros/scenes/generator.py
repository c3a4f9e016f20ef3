"""
Random scenes, for checking promises on scenes nobody tuned anything on.

:func:`random_scene` draws a scene from a seed: a sheet in a vertical plane or a 3D block,
its size and scale, the face it is clamped by, its mass, stiffness (with a contrast between
springs in some), damping (none included), and how its clamp moves (still, shaken along an axis
up to near its resonances, or turned). The same seed gives the same scene on every machine.
"""
from __future__ import annotations

import dataclasses

from modal_spring_ros.core.model.scene import Scene
from modal_spring_ros.scenes.schema import scene_from_dict
import numpy as np

#: Damping ratios drawn from (undamped included: the hardest case for an error that drifts).
DAMPING_RATIOS = (0.0, 0.005, 0.02, 0.05)


def random_scene(seed: int, max_particles: int = 150) -> Scene:
    """Return the random scene of ``seed`` (at most ``max_particles`` particles)."""
    rng = np.random.default_rng(seed)
    spacing = float(rng.uniform(0.03, 0.3))
    if rng.random() < 0.6:
        spec = _sheet(rng, spacing, max_particles)
    else:
        spec = _block(rng, spacing, max_particles)
    spec.update(
        name=f'random_{seed}', description=f'random scene (seed {seed})',
        gravity=[0.0, 0.0, -9.81],
        damping={'ratio': float(rng.choice(DAMPING_RATIOS))},
        anchor_motion=_drive(rng, spec, spacing),
        simulation={'duration': 3.0})
    spec['particles']['mass'] = float(rng.uniform(0.005, 0.05))
    spec['springs']['stiffness'] = float(10 ** rng.uniform(2.3, 3.7))
    scene = scene_from_dict(spec, source=spec['name'])
    if rng.random() < 0.3:  # stiffness contrast: some springs ten times stiffer or softer
        factor = rng.choice([0.1, 10.0])
        contrast = np.where(rng.random(scene.n_springs) < 0.5, factor, 1.0)
        scene = dataclasses.replace(scene, stiffness=np.asarray(scene.stiffness) * contrast)
    return scene


def _sheet(rng: np.random.Generator, spacing: float, max_particles: int) -> dict:
    plane = str(rng.choice(['xz', 'yz']))
    nx = int(rng.integers(3, 13))
    nz = int(rng.integers(3, max(4, min(13, max_particles // nx + 1))))
    face = str(rng.choice(['+z', '-' + plane[0]]))
    return {'dimension': 2, 'plane': plane,
            'particles': {'lattice': {'counts': [nx, nz], 'spacing': spacing,
                                      'origin': [0.0, 0.0, -(nz - 1) * spacing]}},
            'springs': {'connect': ['edges', 'diagonals']},
            'fixed': {'face': face}}


def _block(rng: np.random.Generator, spacing: float, max_particles: int) -> dict:
    ny, nz = int(rng.integers(2, 4)), int(rng.integers(2, 4))
    nx = int(rng.integers(4, max(5, min(13, max_particles // (ny * nz) + 1))))
    return {'dimension': 3,
            'particles': {'lattice': {'counts': [nx, ny, nz], 'spacing': spacing,
                                      'origin': [0.0, 0.0, 0.0]}},
            'springs': {'connect': ['edges', 'diagonals', 'body_diagonals']},
            'fixed': {'face': str(rng.choice(['-x', '+z']))}}


def _drive(rng: np.random.Generator, spec: dict, spacing: float) -> list[dict]:
    kind = rng.choice(['still', 'shake', 'turn'], p=[0.2, 0.55, 0.25])
    axes = ['x', 'y', 'z'] if spec['dimension'] == 3 else list(spec['plane'])
    if kind == 'shake':
        return [{'axis': str(rng.choice(axes)), 'amplitude': float(rng.uniform(0.001, 0.02)),
                 'frequency_hz': float(10 ** rng.uniform(-0.5, 0.8)), 'ramp_s': 0.5}]
    if kind == 'turn':
        normal = 'y' if spec['dimension'] == 3 or spec['plane'] == 'xz' else 'x'
        counts = spec['particles']['lattice']['counts']
        pivot = [0.0, 0.0, 0.0]
        if spec['dimension'] == 2:
            pivot[{'x': 0, 'y': 1}[spec['plane'][0]]] = 0.5 * (counts[0] - 1) * spacing
        return [{'rotation': normal, 'amplitude_deg': float(rng.uniform(5.0, 30.0)),
                 'frequency_hz': float(rng.uniform(0.2, 1.0)), 'pivot': pivot, 'ramp_s': 0.5}]
    return []

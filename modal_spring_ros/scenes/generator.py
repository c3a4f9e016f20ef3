"""
Random scenes, for checking promises on scenes nobody tuned anything on.

:func:`random_scene` draws a scene from a seed: a sheet in a vertical plane or a 3D block,
its size and scale, the face it is clamped by, its mass, stiffness (with a contrast between
springs in some), damping (none included), and how its clamp moves (still, shaken along an axis
up to near its resonances, or turned). :func:`demanding_scene` draws what users bring beyond
that: solids and shells from mesh files, sheets of 5,000 particles and more, clamps turning
+-90 degrees, runs of 20-40 s. The same seed gives the same scene on every machine.
"""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

from modal_spring_ros.core.model.scene import Scene
from modal_spring_ros.scenes.schema import scene_from_dict
import numpy as np
from scipy.spatial import Delaunay
import trimesh

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


#: Particles of a large random sheet (at least; the acceptance's "5k+").
LARGE_SHEET_PARTICLES = (5000, 7000)
#: How long a demanding scene runs, s.
DEMANDING_DURATION_S = (20.0, 40.0)


def demanding_scene(seed: int, folder: Path) -> Scene:
    """
    Return the demanding random scene of ``seed``: what users bring beyond small lattices.

    One of: a solid read from a mesh file and filled as a volume (a torus, capsule, cylinder or
    sphere, turned at random, glued by its lowest slab), a shell from a mesh file (a flat cloth
    irregularly triangulated, or a closed curved skin, an ellipsoid, each hung by its
    highest slab), or a sheet of 5,000-7,000 particles. Its clamp turns +-90 degrees, shakes
    or stays still; it runs 20-40 s. The mesh file is written into ``folder`` (the same bytes for
    the same seed).
    """
    rng = np.random.default_rng(1_000_003 + seed)
    kind = str(rng.choice(['volume', 'flat shell', 'curved shell', 'large sheet'],
                          p=[0.35, 0.2, 0.2, 0.25]))
    duration = float(rng.uniform(*DEMANDING_DURATION_S))
    if kind == 'large sheet':
        spec = _large_sheet(rng)
    else:
        spec = _mesh_spec(rng, kind, folder / f'demanding_{seed}.obj')
    spec.update(name=f'demanding_{seed}', description=f'demanding random scene (seed {seed}): '
                f'{kind}', gravity=[0.0, 0.0, -9.81],
                damping={'ratio': float(rng.choice(DAMPING_RATIOS[1:]))},
                simulation={'duration': duration})
    spec['anchor_motion'] = _large_drive(rng, spec.pop('_pivot'), spec['dimension'])
    return scene_from_dict(spec, source=str(folder / f'{spec["name"]}.yaml'))


def _large_sheet(rng: np.random.Generator) -> dict:
    nx = int(rng.integers(60, 90))
    nz = int(math.ceil(rng.uniform(*LARGE_SHEET_PARTICLES) / nx))
    spacing = 1.0 / (nx - 1)
    return {'dimension': 2, 'plane': 'xz', '_pivot': [0.5, 0.0, 0.0],
            'particles': {'lattice': {'counts': [nx, nz], 'spacing': spacing,
                                      'origin': [0.0, 0.0, -(nz - 1) * spacing]},
                          'mass': float(rng.uniform(2.0, 6.0)) / (nx * nz)},
            'springs': {'connect': ['edges', 'diagonals'],
                        'stiffness': float(10 ** rng.uniform(2.3, 2.9))},
            'fixed': {'face': '+z'}}


def _mesh_spec(rng: np.random.Generator, kind: str, path: Path) -> dict:
    size = float(rng.uniform(0.4, 0.8) if kind == 'flat shell' else rng.uniform(0.1, 0.25))
    if kind == 'flat shell':
        mesh = _cloth(rng, size)
    elif kind == 'curved shell':   # no two triangles in one plane (a flat hinge bends freely)
        mesh = trimesh.creation.icosphere(subdivisions=int(rng.integers(2, 4)), radius=0.5 * size)
        mesh.apply_scale(rng.uniform(0.6, 1.4, 3))
    else:
        mesh = _solid(rng, str(rng.choice(['torus', 'capsule', 'cylinder', 'sphere'])), size)
    if kind != 'flat shell':
        turn = trimesh.transformations.random_rotation_matrix(rng.random(3))
        mesh.apply_transform(turn)
    mesh.export(path)
    low, high = mesh.bounds
    volume = kind == 'volume'
    slab = 0.12 * (high[2] - low[2]) if kind != 'flat shell' else 1e-4 * size
    # a solid stands on its lowest slab; a shell hangs from its highest (in tension, as a cloth
    # or a bag hangs: a skin standing on its base buckles under its weight)
    held = (low[2] - slab, low[2] + slab) if volume else (high[2] - slab, high[2] + slab)
    centre = 0.5 * (low + high)
    # a solid sags under its weight by about density g size / stiffness: at most 8 %
    material = ({'density': 1000.0, 'stiffness': float(10 ** rng.uniform(4.7, 5.2))} if volume
                else {'density': float(rng.uniform(0.2, 1.0)),
                      'stiffness': float(rng.uniform(100.0, 400.0)),
                      'bending': float(10 ** rng.uniform(-5.0, -4.0))} if kind == 'flat shell'
                else {'density': float(rng.uniform(0.2, 1.0)),
                      'stiffness': float(rng.uniform(300.0, 1000.0)),
                      'bending': float(10 ** rng.uniform(-4.0, -3.0))})
    return {'dimension': 3, 'mesh': {'file': str(path), 'kind': 'volume' if volume else
                                     'surface'},
            'material': material,
            '_pivot': [float(centre[0]), float(centre[1]), 0.5 * (held[0] + held[1])],
            'fixed': {'box': {'min': [-10.0, -10.0, held[0]], 'max': [10.0, 10.0, held[1]]}}}


def _solid(rng: np.random.Generator, shape: str, size: float) -> trimesh.Trimesh:
    """Return a closed surface of a few hundred vertices, ``size`` across."""
    sections = int(rng.integers(10, 16))
    if shape == 'torus':
        return trimesh.creation.torus(0.35 * size, 0.15 * size, major_sections=2 * sections,
                                      minor_sections=sections // 2)
    if shape == 'capsule':
        return trimesh.creation.capsule(height=0.6 * size, radius=0.2 * size,
                                        count=[sections, sections])
    if shape == 'cylinder':
        mesh = trimesh.creation.cylinder(radius=0.25 * size, height=size, sections=sections)
        return mesh.subdivide().subdivide()
    return trimesh.creation.icosphere(subdivisions=3, radius=0.5 * size)


def _cloth(rng: np.random.Generator, size: float) -> trimesh.Trimesh:
    """Return a square cloth in the x-z plane, irregularly triangulated (300-900 vertices)."""
    n = int(rng.integers(18, 30))
    u, v = np.meshgrid(np.linspace(0.0, 1.0, n), np.linspace(0.0, 1.0, n), indexing='ij')
    jitter = 0.3 / (n - 1) * (rng.random((2, n, n)) - 0.5)
    inner = (u > 0) & (u < 1) & (v > 0) & (v < 1)
    u, v = u + jitter[0] * inner, v + jitter[1] * inner
    flat = np.column_stack([u.ravel(), v.ravel()])
    triangles = Delaunay(flat).simplices
    vertices = np.column_stack([size * (flat[:, 0] - 0.5), np.zeros(len(flat)),
                                size * flat[:, 1]])
    return trimesh.Trimesh(vertices, triangles, process=False)


def _large_drive(rng: np.random.Generator, pivot: list[float], dimension: int) -> list[dict]:
    kind = rng.choice(['still', 'shake', 'turn'], p=[0.15, 0.35, 0.5])
    if kind == 'shake':
        return [{'axis': str(rng.choice(['x', 'y'] if dimension == 3 else ['x', 'z'])),
                 'amplitude': float(rng.uniform(0.002, 0.02)),
                 'frequency_hz': float(10 ** rng.uniform(-0.7, 0.5)), 'ramp_s': 1.0}]
    if kind == 'turn':
        return [{'rotation': 'y', 'amplitude_deg': 90.0,     # a quarter turn each way
                 'frequency_hz': float(rng.uniform(0.05, 0.3)), 'pivot': pivot,
                 'ramp_s': 2.0}]
    return []

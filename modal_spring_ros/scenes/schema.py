"""
The scene file schema: a scene's YAML (or the mapping it parses to) checked into a Scene.

A scene file is YAML in SI units. Particles and springs are given either explicitly or by a
lattice generator; see ``docs/scenes.md`` for the full format. Every problem found on
load raises :class:`SceneError` with a message that names the field and the problem, so that
command-line tools can print it instead of a traceback.
"""
from __future__ import annotations

import math
from typing import Any, Callable, Mapping

from modal_spring_ros.core.laws import DEFAULT_LAW, SPRING_LAWS
from modal_spring_ros.core.memory_estimate import gib
from modal_spring_ros.core.model.loaded_shape import needs_loaded_shape, settle
from modal_spring_ros.core.model.scene import Damping, Scene, SceneError
from modal_spring_ros.core.motion.anchor_motion import (AnchorMotion, RotationComponent,
                                                        SineComponent)
from modal_spring_ros.scenes.fields.bending_fields import listed_bending
from modal_spring_ros.scenes.fields.contact_fields import contact_field
from modal_spring_ros.scenes.fields.fixed_regions import check_held, fixed_particles
from modal_spring_ros.scenes.fields.limits import (available_memory, BYTES_PER_PARTICLE, LIMITS,
                                                   MAX_STEPS)
from modal_spring_ros.scenes.fields.mesh_fields import mesh_network
from modal_spring_ros.scenes.fields.reader import AXES, DEFAULT_PLANE, FieldReader, PLANES, short
from modal_spring_ros.scenes.files.yaml_reading import load_yaml
from modal_spring_ros.scenes.lattice import lattice_springs
import numpy as np

#: what a scene's modes are taken about: ``rest`` (the shape as built), ``loaded`` (the static
#: equilibrium under gravity, see :mod:`~modal_spring_ros.core.model.loaded_shape`) or ``auto``
#: (loaded when the rest stiffness is singular for want of tension, rest otherwise)
REFERENCES = ('auto', 'rest', 'loaded')


def scene_from_yaml(text: str, source: str = '<scene>', default_name: str = 'scene',
                    progress: Callable[[str], None] | None = None) -> Scene:
    """
    Parse and validate a scene from YAML text.

    Parsing stays within the bounds of :mod:`~modal_spring_ros.scenes.files.yaml_reading`.
    ``progress`` hears of long work (finding the shape a cloth hangs in).
    """
    return scene_from_dict(load_yaml(text, source), source=source, default_name=default_name,
                           progress=progress)


def scene_from_dict(data: Any, source: str = '<scene>', default_name: str = 'scene',
                    progress: Callable[[str], None] | None = None) -> Scene:
    """Validate a scene given as a mapping (the parsed YAML); ``progress`` as above."""
    return _SceneParser(source).parse(data, default_name, progress)


class _SceneParser(FieldReader):
    # -- the scene ----------------------------------------------------------------------------
    def parse(self, data: Any, default_name: str,
              progress: Callable[[str], None] | None = None) -> Scene:
        data = self.mapping(data, 'scene')
        known = {'name', 'description', 'dimension', 'axis', 'plane', 'particles', 'springs',
                 'fixed', 'gravity', 'damping', 'anchor_motion', 'simulation', 'reference',
                 'mesh', 'material', 'triangles', 'bending', 'contact', 'spring_law'}
        unknown = sorted(set(data) - known, key=str)
        if unknown:
            raise self.fail(unknown[0], f"unknown key (known keys: {', '.join(sorted(known))})")
        name = str(data.get('name', default_name))
        dimension = data.get('dimension', 2)
        if isinstance(dimension, bool) or not isinstance(dimension, int) \
                or dimension not in (1, 2, 3):
            raise self.fail('dimension', f'must be 1, 2 or 3, got {short(dimension)}')
        if dimension != 1 and 'axis' in data:
            raise self.fail('axis', 'only a 1D scene (dimension: 1) has an axis')
        if dimension != 2 and 'plane' in data:
            raise self.fail('plane', 'only a 2D scene (dimension: 2) has a plane')
        if dimension == 1:
            axes = (self.axis(data.get('axis', 'x'), 'axis', (0, 1, 2)),)
        elif dimension == 2:
            axes = self.plane(data.get('plane', DEFAULT_PLANE))
            self.pair_axes = axes  # two numbers are in the plane's own coordinates
        else:
            axes = (0, 1, 2)

        if 'mesh' in data:
            (positions, mass, pairs, stiffness, triangles,
             bending) = self.mesh(data, dimension, progress)
        else:
            positions, mass, pairs, stiffness = self.listed(data, axes)
            triangles = self.triangles(data.get('triangles'), positions.shape[0])
            bending = listed_bending(self, data.get('bending'), positions)
        rest_length = self.check_springs(pairs, positions)
        fixed = fixed_particles(self, data.get('fixed'), positions)
        check_held(self, pairs, positions, fixed)

        gravity = self.vector3(data.get('gravity', [0.0, 0.0, 0.0]), 'gravity',
                               LIMITS['gravity'])
        still = [a for a in range(3) if a not in axes]
        if np.any(gravity[still] != 0.0):
            raise self.fail('gravity', f'a {dimension}D scene moves along '
                            f"{', '.join('xyz'[a] for a in axes)} only: gravity must be 0 along "
                            f"{', '.join('xyz'[a] for a in still)}")
        if np.any(positions[:, still] != positions[0, still]):
            raise self.fail('particles', f'a {dimension}D scene must have equal '
                            f"{', '.join('xyz'[a] for a in still)} for every particle")

        damping = self.damping(data.get('damping', {}))
        anchor_motion = self.anchor_motion(data.get('anchor_motion', []), axes)
        sim = self.mapping(data.get('simulation', {}) or {}, 'simulation')
        dt = sim.get('dt')
        default_dt = None if dt is None else self.number(dt, 'simulation.dt', positive=True,
                                                         limit=LIMITS['dt'])
        duration = self.number(sim.get('duration', 5.0), 'simulation.duration', positive=True,
                               limit=LIMITS['duration'])
        if default_dt is not None and duration / default_dt > MAX_STEPS:
            raise self.fail('simulation.dt', f'{default_dt:g} s makes '
                            f'{duration / default_dt:.3g} steps of the {duration:g} s run (at '
                            f'most {MAX_STEPS:.0e}): a step this small does not advance '
                            'the simulation in any useful time')

        def frozen(a: np.ndarray) -> np.ndarray:
            a.setflags(write=False)
            return a

        reference = self.choice(data.get('reference', 'auto'), 'reference', REFERENCES)
        scene = Scene(
            name=name,
            dimension=int(dimension),
            axes=axes,
            rest_positions=frozen(positions),
            mass=frozen(mass),
            springs=frozen(pairs),
            stiffness=frozen(stiffness),
            rest_length=frozen(rest_length),
            fixed=frozen(fixed),
            gravity=frozen(gravity),
            damping=damping,
            anchor_motion=anchor_motion,
            default_dt=default_dt,
            default_duration=duration,
            description=str(data.get('description', '')),
            triangles=None if triangles is None else frozen(triangles),
            bending=bending,
            contact=contact_field(self, data.get('contact'), positions),
            spring_law=self.choice(data.get('spring_law', DEFAULT_LAW), 'spring_law',
                                   SPRING_LAWS),
        )
        if reference == 'loaded' or (reference == 'auto' and needs_loaded_shape(scene)):
            try:
                scene = settle(scene, progress)
            except SceneError as error:
                raise self.fail('reference', str(error)) from None
        return scene

    def listed(self, data: Mapping[str, Any], axes: tuple[int, ...]):
        """Return positions, masses, spring pairs and stiffness given by lattice or by list."""
        if 'material' in data:
            raise self.fail('material', 'only a mesh scene has a material (particles and '
                            'springs carry their own mass and stiffness)')
        particles = self.mapping(self.required(data, 'particles', 'scene'), 'particles')
        positions, lattice = self.positions(particles, axes)
        n = positions.shape[0]
        mass = self.per_item(self.required(particles, 'mass', 'particles'), n,
                             'particles.mass', 'particles', LIMITS['mass'])
        springs_spec = self.mapping(self.required(data, 'springs', 'scene'), 'springs')
        pairs = self.pairs(springs_spec, n, lattice)
        stiffness = self.per_item(self.required(springs_spec, 'stiffness', 'springs'),
                                  len(pairs), 'springs.stiffness', 'springs',
                                  LIMITS['stiffness'])
        return positions, mass, pairs, stiffness

    def mesh(self, data: Mapping[str, Any], dimension: int,
             progress: Callable[[str], None] | None = None):
        """Return what :meth:`listed` does, and the skin's triangles, built from a mesh."""
        if dimension != 3:
            raise self.fail('mesh', 'a mesh scene is 3D: give dimension: 3')
        for key in ('particles', 'springs', 'triangles', 'bending'):
            if key in data:
                raise self.fail(key, 'a mesh scene takes its particles, springs and '
                                f'triangles from its mesh: leave {key} out')
        network = mesh_network(self, data['mesh'], data.get('material'), self.check_size,
                               progress)
        bad = np.flatnonzero(~(network.mass > 0.0))
        if bad.size:
            raise self.fail('mesh', f'vertex {int(bad[0])} has no mass (on no cell)')
        return (network.positions, network.mass, network.springs, network.stiffness,
                network.triangles, network.bending)

    def triangles(self, value: Any, n: int) -> np.ndarray | None:
        """Read the triangles a listed scene shows as its mesh; None when not given."""
        if value is None:
            return None
        tri = np.asarray(value) if isinstance(value, (list, tuple)) else None
        if (tri is None or tri.ndim != 2 or tri.shape[1] != 3 or tri.shape[0] == 0
                or tri.dtype.kind not in 'iu'):
            raise self.fail('triangles', 'must be a list of [i, j, k] particle indices')
        if tri.min() < 0 or tri.max() >= n:
            raise self.fail('triangles', f'particle index out of range (0..{n - 1})')
        return tri.astype(np.int64)

    def plane(self, value: Any) -> tuple[int, int]:
        """Return the world axes of the plane a 2D scene lives in: ``xz`` is x across, z up."""
        value = self.choice(value, 'plane', PLANES)
        return AXES[value[0]], AXES[value[1]]

    def positions(self, particles: Mapping[str, Any], axes: tuple[int, ...]
                  ) -> tuple[np.ndarray, tuple[int, ...] | None]:
        """
        Return the particle positions, and the lattice counts when a lattice generated them.

        A lattice's counts and spacing go along the scene's ``axes`` in order (a 2D sheet in the
        x-z plane: its first count along x, its second along z).
        """
        dimension = len(axes)
        has_lattice = 'lattice' in particles
        has_positions = 'positions' in particles
        if has_lattice == has_positions:
            raise self.fail('particles', "give exactly one of 'positions' or 'lattice'")
        if has_positions:
            raw = particles['positions']
            if not isinstance(raw, (list, tuple)) or not raw:
                raise self.fail('particles.positions', 'must be a non-empty list of points')
            self.check_size(len(raw), 'particles.positions')
            pos = np.array([self.vector3(p, f'particles.positions[{i}]', LIMITS['position'])
                            for i, p in enumerate(raw)])
            return pos, None
        lat = self.mapping(particles['lattice'], 'particles.lattice')
        counts = lat.get('counts')
        if (not isinstance(counts, (list, tuple)) or len(counts) != dimension
                or not all(isinstance(c, int) and not isinstance(c, bool) and c >= 1
                           for c in counts)):
            raise self.fail('particles.lattice.counts',
                            f'must be {dimension} positive integers, got {short(counts)}')
        self.check_size(math.prod(counts), 'particles.lattice.counts')
        spacing = lat.get('spacing', 1.0)
        if isinstance(spacing, (list, tuple)):
            sp = [self.number(s, f'particles.lattice.spacing[{i}]', positive=True,
                              limit=LIMITS['position'])
                  for i, s in enumerate(spacing)]
            if len(sp) != dimension:
                raise self.fail('particles.lattice.spacing',
                                f'must have {dimension} values, got {len(sp)}')
        else:
            sp = [self.number(spacing, 'particles.lattice.spacing', positive=True,
                              limit=LIMITS['position'])] * dimension
        origin = self.vector3(lat.get('origin', [0.0, 0.0, 0.0]), 'particles.lattice.origin',
                              LIMITS['position'])
        grids = np.meshgrid(*[np.arange(c) * s for c, s in zip(counts, sp)], indexing='ij')
        # Scene order: x fastest, then y, then z (row by row).
        coords = [g.transpose().ravel() for g in grids]
        pos = np.zeros((coords[0].size, 3))
        for axis, c in zip(axes, coords):
            pos[:, axis] = c
        return pos + origin, tuple(int(c) for c in counts)

    def pairs(self, springs: Mapping[str, Any], n: int,
              lattice: tuple[int, ...] | None) -> np.ndarray:
        has_pairs = 'pairs' in springs
        has_connect = 'connect' in springs
        if has_pairs == has_connect:
            raise self.fail('springs', "give exactly one of 'pairs' or 'connect'")
        if has_connect:
            if lattice is None:
                raise self.fail('springs.connect', 'needs particles.lattice')
            kinds = springs['connect']
            if isinstance(kinds, str):
                kinds = [kinds]
            if not isinstance(kinds, (list, tuple)) or not kinds:
                raise self.fail('springs.connect', f'must be a kind or a list of kinds, got '
                                f'{short(kinds)}')
            allowed = ('edges', 'diagonals', 'body_diagonals')
            for i, kind in enumerate(kinds):
                if not isinstance(kind, str) or kind not in allowed:
                    raise self.fail(f'springs.connect[{i}]',
                                    f"unknown {short(kind)} (one of {', '.join(allowed)})")
            return lattice_springs(lattice, kinds)
        raw = springs['pairs']
        if not isinstance(raw, (list, tuple)) or not raw:
            raise self.fail('springs.pairs', 'must be a non-empty list of [i, j] pairs')
        out = np.empty((len(raw), 2), dtype=np.int64)
        for e, pair in enumerate(raw):
            if (not isinstance(pair, (list, tuple)) or len(pair) != 2
                    or not all(isinstance(v, int) and not isinstance(v, bool) for v in pair)):
                raise self.fail(f'springs.pairs[{e}]', f'must be two integers, got {pair!r}')
            for v in pair:
                if not 0 <= v < n:
                    raise self.fail(f'springs.pairs[{e}]',
                                    f'particle index {v} out of range (0..{n - 1})')
            if pair[0] == pair[1]:
                raise self.fail(f'springs.pairs[{e}]',
                                f'connects particle {pair[0]} to itself')
            out[e] = sorted(pair)
        seen: dict[tuple[int, int], int] = {}
        for e, (i, j) in enumerate(out.tolist()):
            if (i, j) in seen:
                raise self.fail(f'springs.pairs[{e}]',
                                f'duplicate spring {i}-{j} (same as springs.pairs[{seen[i, j]}])')
            seen[i, j] = e
        return out

    def check_springs(self, pairs: np.ndarray, positions: np.ndarray) -> np.ndarray:
        lengths = np.linalg.norm(positions[pairs[:, 1]] - positions[pairs[:, 0]], axis=1)
        scale = float(np.max(lengths)) if lengths.size else 1.0
        short = np.flatnonzero(lengths <= 1e-12 * max(scale, 1e-300))
        if short.size:
            e = int(short[0])
            i, j = pairs[e]
            raise self.fail(f'springs.pairs[{e}]',
                            f'zero-length spring: particles {i} and {j} are at the same position')
        return lengths

    def check_size(self, particles: int, field: str) -> None:
        """Refuse a scene that would not fit in the memory available, before building it."""
        need = particles * BYTES_PER_PARTICLE
        have = available_memory()
        if need > have:
            raise self.fail(field, f'{particles:,} particles need at least {gib(need)} to build '
                            f'and run, and {gib(have)} are available')

    def damping(self, spec: Any) -> Damping:
        spec = self.mapping(spec or {}, 'damping')
        unknown = sorted(set(spec) - {'ratio', 'rayleigh'}, key=str)
        if unknown:
            raise self.fail(f'damping.{unknown[0]}', "unknown key (use 'ratio' or 'rayleigh')")
        ratio = self.number(spec.get('ratio', 0.0), 'damping.ratio', non_negative=True,
                            limit=LIMITS['damping.ratio'])
        ray = self.mapping(spec.get('rayleigh', {}) or {}, 'damping.rayleigh')
        alpha = self.number(ray.get('alpha', 0.0), 'damping.rayleigh.alpha', non_negative=True,
                            limit=LIMITS['damping.alpha'])
        beta = self.number(ray.get('beta', 0.0), 'damping.rayleigh.beta', non_negative=True,
                           limit=LIMITS['damping.beta'])
        return Damping(ratio, alpha, beta)

    def anchor_motion(self, spec: Any, axes: tuple[int, ...]) -> AnchorMotion:
        """Read translation terms (``axis``) and rotation terms (``rotation``), in order."""
        if spec is None:
            return AnchorMotion(())
        if not isinstance(spec, (list, tuple)):
            raise self.fail('anchor_motion', 'must be a list of sine components')
        moves, turns = [], []
        for k, item in enumerate(spec):
            field = f'anchor_motion[{k}]'
            item = self.mapping(item, field)
            if 'rotation' in item:
                turns.append(self.rotation(item, field, axes))
                continue
            self.known_keys(item, field, _TRANSLATION_KEYS)
            moves.append(SineComponent(
                axis=self.axis(item.get('axis'), f'{field}.axis', axes),
                amplitude=self.number(item.get('amplitude'), f'{field}.amplitude',
                                      limit=LIMITS['amplitude']),
                **self.sine_timing(item, field)))
        return AnchorMotion(tuple(moves), tuple(turns))

    def rotation(self, item: Mapping[str, Any], field: str, axes: tuple[int, ...]
                 ) -> RotationComponent:
        """Return a turn about an axis through a pivot; a 2D scene turns only about its normal."""
        self.known_keys(item, field, _ROTATION_KEYS)
        if len(axes) == 1:
            raise self.fail(f'{field}.rotation', 'a 1D scene cannot turn (it moves along '
                            f"{'xyz'[axes[0]]} only)")
        normal = tuple(a for a in range(3) if a not in axes) if len(axes) == 2 else (0, 1, 2)
        value = item['rotation']
        if not isinstance(value, str) or value not in AXES:
            raise self.fail(f'{field}.rotation', f'must be one of x, y, z, got {short(value)}')
        if AXES[value] not in normal:
            raise self.fail(f'{field}.rotation', f'a turn about {value} leaves the '
                            f"{''.join('xyz'[a] for a in axes)} plane of this 2D scene: turn "
                            f"about {'xyz'[normal[0]]}")
        if 'pivot' not in item:
            raise self.fail(f'{field}.pivot', 'missing: the point the axis goes through, '
                            '[x, y, z]')
        pivot = self.vector3(item['pivot'], f'{field}.pivot', LIMITS['position'])
        degrees = self.number(self.required(item, 'amplitude_deg', field),
                              f'{field}.amplitude_deg', limit=LIMITS['amplitude_deg'])
        return RotationComponent(axis=AXES[value], amplitude=math.radians(degrees),
                                 pivot=tuple(float(p) for p in pivot),
                                 **self.sine_timing(item, field))

    def sine_timing(self, item: Mapping[str, Any], field: str) -> dict[str, float]:
        """Return a sine term's frequency, phase and ramp."""
        return {
            'frequency_hz': self.number(item.get('frequency_hz'), f'{field}.frequency_hz',
                                        non_negative=True, limit=LIMITS['frequency_hz']),
            'phase': self.number(item.get('phase', 0.0), f'{field}.phase',
                                 limit=LIMITS['phase']),
            'ramp_s': self.number(item.get('ramp_s', 0.0), f'{field}.ramp_s',
                                  non_negative=True, limit=LIMITS['ramp_s']),
        }


_TRANSLATION_KEYS = ('axis', 'amplitude', 'frequency_hz', 'phase', 'ramp_s')
_ROTATION_KEYS = ('rotation', 'amplitude_deg', 'frequency_hz', 'phase', 'ramp_s', 'pivot')

"""
A scene file's ``fixed`` field: which particles the clamp holds.

```yaml
fixed: {indices: [0, 9]}                      # by number
fixed: {face: +z}                             # the particles on a face of the bounding box
fixed: {box: {min: [x, y, z], max: [x, y, z]}}  # inside an axis-aligned box (edges included)
fixed: {near: {point: [x, y, z], radius: r}}  # within r of a point; a list of them for several
```

Any of them together: a particle is fixed when any of them holds it. Each region must hold at
least one particle (a region that misses the object is a typo, not a choice), and every part of
the object (the particles springs join) must hold one (:func:`check_held`): a part held by
nothing floats off, and its stiffness has rigid-body zero modes.
"""
from __future__ import annotations

from typing import Any

from modal_spring_ros.scenes.fields.limits import LIMITS
from modal_spring_ros.scenes.fields.reader import AXES, FieldReader
import numpy as np
import scipy.sparse
from scipy.sparse.csgraph import connected_components

FIXED_KEYS = ('indices', 'face', 'box', 'near')


def fixed_particles(reader: FieldReader, spec: Any, positions: np.ndarray) -> np.ndarray:
    """Return the (n,) bool mask of the particles the scene's ``fixed`` field names."""
    n = positions.shape[0]
    if spec is None:
        raise reader.fail('fixed', 'missing: at least one particle must be fixed, otherwise '
                          'the stiffness has rigid-body zero modes')
    spec = reader.mapping(spec, 'fixed')
    unknown = sorted(set(spec) - set(FIXED_KEYS), key=str)
    if unknown:
        raise reader.fail(f'fixed.{unknown[0]}',
                          f"unknown key (use {', '.join(FIXED_KEYS)})")
    fixed = np.zeros(n, dtype=bool)
    if 'indices' in spec:
        idx = spec['indices']
        if not isinstance(idx, (list, tuple)):
            raise reader.fail('fixed.indices', 'must be a list of particle indices')
        for k, v in enumerate(idx):
            if not isinstance(v, int) or isinstance(v, bool) or not 0 <= v < n:
                raise reader.fail(f'fixed.indices[{k}]',
                                  f'particle index {v!r} out of range (0..{n - 1})')
            fixed[v] = True
    if 'face' in spec:
        face = spec['face']
        if not isinstance(face, str) or len(face) != 2 or face[0] not in '+-' \
                or face[1] not in AXES:
            raise reader.fail('fixed.face', f'must be one of +x -x +y -y +z -z, got {face!r}')
        coord = positions[:, AXES[face[1]]]
        edge = coord.max() if face[0] == '+' else coord.min()
        tol = 1e-9 * max(1.0, float(np.ptp(positions)))
        fixed |= np.abs(coord - edge) <= tol
    if 'box' in spec:
        fixed |= _held(reader, 'fixed.box', _in_box(reader, spec['box'], positions))
    if 'near' in spec:
        near = spec['near']
        for k, item in enumerate(near if isinstance(near, (list, tuple)) else [near]):
            field = f'fixed.near[{k}]' if isinstance(near, (list, tuple)) else 'fixed.near'
            fixed |= _held(reader, field, _near(reader, item, field, positions))
    if not fixed.any():
        raise reader.fail('fixed', 'no particle is fixed: at least one must be, otherwise the '
                          'stiffness has rigid-body zero modes')
    if fixed.all():
        raise reader.fail('fixed', 'every particle is fixed: nothing can move')
    return fixed


def _in_box(reader: FieldReader, spec: Any, positions: np.ndarray) -> np.ndarray:
    spec = reader.mapping(spec, 'fixed.box')
    reader.known_keys(spec, 'fixed.box', ('min', 'max'))
    low = reader.vector3(reader.required(spec, 'min', 'fixed.box'), 'fixed.box.min',
                         LIMITS['position'])
    high = reader.vector3(reader.required(spec, 'max', 'fixed.box'), 'fixed.box.max',
                          LIMITS['position'])
    if np.any(low > high):
        raise reader.fail('fixed.box', 'min must not exceed max on any axis')
    slack = 1e-9 * max(1.0, float(np.max(np.ptp(positions, axis=0))))
    return np.all((positions >= low - slack) & (positions <= high + slack), axis=1)


def _near(reader: FieldReader, spec: Any, field: str, positions: np.ndarray) -> np.ndarray:
    spec = reader.mapping(spec, field)
    reader.known_keys(spec, field, ('point', 'radius'))
    point = reader.vector3(reader.required(spec, 'point', field), f'{field}.point',
                           LIMITS['position'])
    radius = reader.number(reader.required(spec, 'radius', field), f'{field}.radius',
                           positive=True, limit=LIMITS['position'])
    return np.linalg.norm(positions - point, axis=1) <= radius


def _held(reader: FieldReader, field: str, mask: np.ndarray) -> np.ndarray:
    if not mask.any():
        raise reader.fail(field, 'holds no particle: the region misses the object')
    return mask


def check_held(reader: FieldReader, pairs: np.ndarray, positions: np.ndarray,
               fixed: np.ndarray) -> None:
    """
    Check that a spring reaches every particle, and that every part of the object is held.

    A part is a set of particles springs join (a mesh of two bodies, a lattice cut in two); one
    without a fixed particle is named: how many parts are loose, the largest one's size, centre
    and first particles.
    """
    n = positions.shape[0]
    lonely = np.flatnonzero(np.bincount(pairs.ravel(), minlength=n) == 0)
    if lonely.size:
        raise reader.fail('springs', f'{lonely.size} particle(s) no spring reaches: '
                          + _listed(lonely))
    graph = scipy.sparse.coo_matrix((np.ones(pairs.shape[0]), (pairs[:, 0], pairs[:, 1])),
                                    shape=(n, n))
    parts, labels = connected_components(graph, directed=False)
    held = np.zeros(parts, dtype=bool)
    held[labels[fixed]] = True
    loose = np.flatnonzero(~held)
    if loose.size:
        sizes = np.bincount(labels, minlength=parts)
        largest = np.flatnonzero(labels == loose[np.argmax(sizes[loose])])
        centre = ', '.join(f'{c:.3g}' for c in positions[largest].mean(axis=0))
        verb = 'holds' if loose.size == 1 else 'hold'
        raise reader.fail('fixed', f"{loose.size} of the object's {parts} parts (particles "
                          f'joined by springs) {verb} no fixed particle, so nothing holds it: '
                          f'the largest, {largest.size} particles around ({centre}), is '
                          f'particles {_listed(largest)}; fix a particle of each part, or join '
                          'it to a held one with springs')


def _listed(indices: np.ndarray) -> str:
    return ', '.join(str(i) for i in indices[:10]) + (' ...' if indices.size > 10 else '')

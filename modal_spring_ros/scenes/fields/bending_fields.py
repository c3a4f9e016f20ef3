"""
A listed scene's ``bending`` field: the quadratic bending of a surface, hinge by hinge.

```yaml
bending:
  hinges: [[0, 1, 2, 3], ...]          # an edge's two particles, then the two across it
  weights: [[0.8, 0.7, -0.9, -0.6], ...]  # sqrt(c_e) times the hinge's weights
```

What a mesh scene's flat surface gets from ``material.bending``
(:mod:`~modal_spring_ros.core.model.bending`), written out particle by particle: how runs and
bags keep it. The weights of each hinge must vanish on the shape as built (sum to zero, weight
the four positions to zero), or that shape would not be at rest.
"""
from __future__ import annotations

from typing import Any

from modal_spring_ros.core.model.bending import Bending
from modal_spring_ros.scenes.fields.limits import LIMITS
from modal_spring_ros.scenes.fields.reader import FieldReader, short
import numpy as np

#: a hinge's weighted rest positions may be this share of its weights times the object's size
REST_RTOL = 1e-6
BENDING_KEYS = ('hinges', 'weights')


def listed_bending(reader: FieldReader, value: Any, positions: np.ndarray) -> Bending | None:
    """Read ``bending`` of a listed scene (None when not given); one-line refusals."""
    if value is None:
        return None
    spec = reader.mapping(value, 'bending')
    reader.known_keys(spec, 'bending', BENDING_KEYS)
    hinges = _table(reader, reader.required(spec, 'hinges', 'bending'), 'bending.hinges', 'iu')
    weights = _table(reader, reader.required(spec, 'weights', 'bending'), 'bending.weights',
                     'iuf').astype(float)
    if weights.shape != hinges.shape:
        raise reader.fail('bending.weights', f'has {weights.shape[0]} rows for '
                          f'{hinges.shape[0]} hinges')
    n = positions.shape[0]
    if hinges.size and (hinges.min() < 0 or hinges.max() >= n):
        raise reader.fail('bending.hinges', f'particle index out of range (0..{n - 1})')
    sorted_rows = np.sort(hinges, axis=1)
    repeated = np.flatnonzero(np.any(sorted_rows[:, 1:] == sorted_rows[:, :-1], axis=1))
    if repeated.size:
        raise reader.fail(f'bending.hinges[{int(repeated[0])}]',
                          'names a particle twice (a hinge joins four particles)')
    if not np.all(np.isfinite(weights)) or np.max(np.abs(weights), initial=0.0) > LIMITS[
            'stiffness']:
        raise reader.fail('bending.weights', 'must be finite numbers of at most '
                          f"{LIMITS['stiffness']:g} in size")
    size = max(float(np.max(np.ptp(positions, axis=0))), 1e-300)
    scale = np.abs(weights).sum(axis=1)
    bending = Bending(hinges, weights)
    off = np.maximum(np.abs(weights.sum(axis=1)) * size, bending.residual(positions))
    bad = np.flatnonzero(off > REST_RTOL * scale * size)
    if bad.size:
        raise reader.fail(f'bending.weights[{int(bad[0])}]',
                          'does not vanish on the shape as built (the weights must sum to zero '
                          'and weight the four positions to zero)'
                          + (f'; {bad.size - 1} more hinges too' if bad.size > 1 else ''))
    hinges.setflags(write=False)
    weights.setflags(write=False)
    return bending


def _table(reader: FieldReader, value: Any, field: str, kinds: str) -> np.ndarray:
    """Return a list of rows of four numbers of ``kinds`` as an (H, 4) array."""
    table = None
    if isinstance(value, (list, tuple)):
        try:
            table = np.array(value)
        except ValueError:  # rows of different lengths
            table = None
    if table is None or not (table.ndim == 2 and table.shape[1] == 4 or table.size == 0) \
            or table.dtype.kind not in kinds:
        raise reader.fail(field, 'must be a list of rows of four '
                          + ('particle indices' if kinds == 'iu' else 'numbers')
                          + f', got {short(value)}')
    return table.reshape(-1, 4).astype(np.int64 if kinds == 'iu' else float)

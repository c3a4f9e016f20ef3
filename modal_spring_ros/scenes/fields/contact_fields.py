"""
A scene's ``contact`` field: the colliders the object touches, and the friction.

```yaml
contact:
  friction: 0.4                    # or {static: 0.5, sliding: 0.4}
  colliders:
    - {shape: plane, point: [0, 0, 0], normal: [0, 0, 1]}
    - {shape: sphere, center: [0, 0, 0.3], radius: 0.1}
    - {shape: box, center: [0.3, 0, 0.1], half_extents: [0.1, 0.1, 0.1]}
    - {shape: capsule, a: [0, 0, -0.03], b: [0, 0, 0.03], radius: 0.01, frame: tool0}
    - {shape: cylinder, center: [0, 0, 0.1], axis: [0, 0, 1], radius: 0.05, half_length: 0.1}
```

A collider is fixed in the world, or attached to a TF frame (``frame``: its shape given in
that frame's coordinates, placed where TF says it is once it does;
:mod:`~modal_spring_ros.core.model.colliders`); each refusal names its field.
"""
from __future__ import annotations

import re
from typing import Any

from modal_spring_ros.core.model.colliders import Contact, SHAPES
from modal_spring_ros.scenes.fields.limits import LIMITS
from modal_spring_ros.scenes.fields.reader import FieldReader, short
import numpy as np

#: each shape's fields: vectors (3 numbers) and lengths (positive numbers)
SHAPE_FIELDS = {'plane': (('point', 'normal'), ()), 'sphere': (('center',), ('radius',)),
                'box': (('center', 'half_extents'), ()),
                'capsule': (('a', 'b'), ('radius',)),
                'cylinder': (('center', 'axis'), ('radius', 'half_length'))}
#: most colliders in a scene (each costs a pass over the particles every step)
MAX_COLLIDERS = 64
MAX_FRAME_NAME = 256
FRAME_NAME = re.compile(r'[A-Za-z0-9_][A-Za-z0-9_/.\-]*')
#: the largest friction coefficient taken
MAX_FRICTION = 10.0
#: a particle this far inside a collider as built is taken (resting on it, as contact holds)
RESTING_DEPTH = 1e-3


def contact_field(reader: FieldReader, value: Any, positions: np.ndarray) -> Contact | None:
    """
    Read ``contact`` (None when not given); one-line refusals.

    A collider may not hold a particle of the shape as built (``positions``) deeper than
    :data:`RESTING_DEPTH` (resting on it): contact keeps particles out, it does not pull a mesh
    out of a solid it was built through.
    """
    if value is None:
        return None
    spec = reader.mapping(value, 'contact')
    reader.known_keys(spec, 'contact', ('friction', 'colliders'))
    static, sliding = _friction(reader, spec.get('friction', 0.0))
    items = reader.required(spec, 'colliders', 'contact')
    if not isinstance(items, list) or not 1 <= len(items) <= MAX_COLLIDERS:
        raise reader.fail('contact.colliders', f'must be a list of 1 to {MAX_COLLIDERS} '
                          f'colliders, got {short(items)}')
    colliders = tuple(_collider(reader, item, f'contact.colliders[{i}]')
                      for i, item in enumerate(items))
    frames = tuple(_frame(reader, item.get('frame', ''), f'contact.colliders[{i}].frame')
                   for i, item in enumerate(items))
    for i, collider in enumerate(colliders):
        if frames[i]:
            continue        # where the frame puts it is known at run time (TF)
        inside = np.flatnonzero(collider.distance(positions)[0] < -RESTING_DEPTH)
        if inside.size:
            raise reader.fail(f'contact.colliders[{i}]', f'{inside.size} particles (particle '
                              f'{int(inside[0])} first) are inside this {collider.shape} as '
                              f'built (deeper than {RESTING_DEPTH * 1e3:g} mm): the object must '
                              'start outside every collider, or resting on it')
    return Contact(colliders, static, sliding, frames if any(frames) else ())


def _frame(reader: FieldReader, value: Any, field: str) -> str:
    """Return a TF frame name ('' for none): letters, digits, ``_``, ``/``, ``-`` and ``.``."""
    if not isinstance(value, str) or len(value) > MAX_FRAME_NAME or (
            value and not FRAME_NAME.fullmatch(value.lstrip('/'))):
        raise reader.fail(field, f'must be a TF frame name (letters, digits, _ / - .), got '
                          f'{short(value)}')
    return value.lstrip('/')


def _friction(reader: FieldReader, value: Any) -> tuple[float, float]:
    if isinstance(value, dict):
        reader.known_keys(value, 'contact.friction', ('static', 'sliding'))
        static = reader.number(reader.required(value, 'static', 'contact.friction'),
                               'contact.friction.static', non_negative=True,
                               limit=MAX_FRICTION)
        sliding = reader.number(value.get('sliding', static), 'contact.friction.sliding',
                                non_negative=True, limit=MAX_FRICTION)
        if sliding > static:
            raise reader.fail('contact.friction.sliding', f'({sliding:g}) must not be above '
                              f'the static friction ({static:g})')
        return static, sliding
    mu = reader.number(value, 'contact.friction', non_negative=True, limit=MAX_FRICTION)
    return mu, mu


def _collider(reader: FieldReader, value: Any, field: str):
    item = reader.mapping(value, field)
    shape = reader.choice(item.get('shape'), f'{field}.shape', SHAPES)
    vectors, lengths = SHAPE_FIELDS[shape]
    reader.known_keys(item, field, ('shape', 'frame') + vectors + lengths)
    values: dict[str, Any] = {}
    for key in vectors:
        values[key] = reader.vector3(reader.required(item, key, field), f'{field}.{key}',
                                     LIMITS['position'])
    for key in lengths:
        values[key] = reader.number(reader.required(item, key, field), f'{field}.{key}',
                                    positive=True, limit=LIMITS['position'])
    for key in ('normal', 'axis'):
        if key in values and not np.linalg.norm(values[key]) > 0.0:
            raise reader.fail(f'{field}.{key}', 'must not be zero')
    if shape == 'box' and not np.all(values['half_extents'] > 0.0):
        raise reader.fail(f'{field}.half_extents', 'must be three positive numbers')
    if shape == 'capsule' and np.array_equal(values['a'], values['b']):
        raise reader.fail(f'{field}.b', 'must differ from a (or use a sphere)')
    return SHAPES[shape](**values)

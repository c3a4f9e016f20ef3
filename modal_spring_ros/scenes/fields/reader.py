"""
Typed reading of a scene file's fields.

Numbers, vectors, axes, mappings, each with a one-line refusal that names the field.
"""
from __future__ import annotations

import math
import re
from typing import Any, Mapping

from modal_spring_ros.core.model.scene import SceneError
import numpy as np

AXES = {'x': 0, 'y': 1, 'z': 2}
#: The world planes a 2D scene can live in; the default hangs it in the vertical x-z plane of
#: a z-up world (REP 103).
PLANES = ('xz', 'xy', 'yz')
DEFAULT_PLANE = 'xz'
#: a decimal number as YAML 1.2 spells it (YAML 1.1 reads some of these as text)
DECIMAL = re.compile(r'[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?')


class FieldReader:
    """
    Typed reading of a parsed YAML document's fields.

    Each problem is a :class:`SceneError` naming the source and the field.
    """

    def __init__(self, source: str):
        self.source = source
        #: the world axes a vector of two numbers gives (a 2D scene's plane: in-plane values)
        self.pair_axes: tuple[int, int] = (0, 1)

    def fail(self, field: str, problem: str) -> SceneError:
        return SceneError(f'{self.source}: {field}: {problem}')

    # -- small typed getters ------------------------------------------------------------------
    def mapping(self, value: Any, field: str) -> Mapping[str, Any]:
        if not isinstance(value, Mapping):
            raise self.fail(field, f'must be a mapping, got {type(value).__name__}')
        return value

    def number(self, value: Any, field: str, *, positive: bool = False,
               non_negative: bool = False, limit: float = math.inf) -> float:
        """
        Return a finite number, at most ``limit`` in size.

        YAML 1.1 reads ``1e-4`` and ``1.0e308`` (an exponent without a sign, or no dot) as text;
        such text is taken as the number it spells.
        """
        if isinstance(value, str) and DECIMAL.fullmatch(value.strip()):
            value = float(value)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(field, f'must be a number, got {short(value)}')
        try:
            value = float(value)
        except OverflowError:
            raise self.fail(field, f'must be at most {limit:g} in size, got an integer of '
                            f'{len(str(abs(value)))} digits') from None
        if not math.isfinite(value):
            raise self.fail(field, f'must be finite, got {value}')
        if abs(value) > limit:
            raise self.fail(field, f'must be at most {limit:g} in size, got {value:g}')
        if positive and value <= 0.0:
            raise self.fail(field, f'must be positive, got {value:g}')
        if non_negative and value < 0.0:
            raise self.fail(field, f'must not be negative, got {value:g}')
        return value

    def per_item(self, value: Any, count: int, field: str, what: str, limit: float
                 ) -> np.ndarray:
        """Return a positive scalar broadcast to ``count`` items, or ``count`` of them."""
        if isinstance(value, (list, tuple)):
            if len(value) != count:
                raise self.fail(field, f'has {len(value)} values for {count} {what}')
            arr = np.array([self.number(v, f'{field}[{i}]', limit=limit)
                            for i, v in enumerate(value)])
        else:
            arr = np.full(count, self.number(value, field, limit=limit))
        bad = np.flatnonzero(arr <= 0.0)
        if bad.size:
            i = int(bad[0])
            name = f'{field}[{i}]' if isinstance(value, (list, tuple)) else field
            raise self.fail(name, f'must be positive, got {arr[i]:g}'
                            + (f' ({bad.size} {what} affected)' if bad.size > 1 else ''))
        return arr

    def vector3(self, value: Any, field: str, limit: float) -> np.ndarray:
        """Return a world vector: three numbers, or two along :attr:`pair_axes`."""
        if not isinstance(value, (list, tuple)) or len(value) not in (2, 3):
            raise self.fail(field, f'must be a list of 2 or 3 numbers, got {short(value)}')
        out = np.zeros(3)
        for i, (axis, v) in enumerate(zip(self.pair_axes if len(value) == 2 else (0, 1, 2),
                                          value)):
            out[axis] = self.number(v, f'{field}[{i}]', limit=limit)
        return out

    def axis(self, value: Any, field: str, allowed: tuple[int, ...]) -> int:
        if not isinstance(value, str) or value not in AXES or AXES[value] not in allowed:
            raise self.fail(field, f"must be one of {', '.join('xyz'[a] for a in allowed)}, "
                            f'got {short(value)}')
        return AXES[value]

    def choice(self, value: Any, field: str, choices) -> str:
        """Return ``value``, one of the names ``choices`` (else the error lists them)."""
        if not isinstance(value, str) or value not in choices:
            raise self.fail(field, f"must be one of {', '.join(choices)}, got {short(value)}")
        return value

    def required(self, spec: Mapping[str, Any], key: str, parent: str) -> Any:
        if key not in spec:
            raise self.fail(f'{parent}.{key}', 'missing')
        return spec[key]

    def known_keys(self, item: Mapping[str, Any], field: str, known: tuple[str, ...]) -> None:
        unknown = sorted(set(item) - set(known), key=str)
        if unknown:
            raise self.fail(f'{field}.{unknown[0]}',
                            f"unknown key (known keys: {', '.join(known)})")


def short(value: Any, limit: int = 60) -> str:
    """``repr(value)``, cut short: a message stays one readable line."""
    text = repr(value)
    return text if len(text) <= limit else text[:limit - 3] + '...'

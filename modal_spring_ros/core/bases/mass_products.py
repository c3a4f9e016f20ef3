"""Products with the lumped mass matrix that large bases need, made without big temporaries."""
from __future__ import annotations

import numpy as np

#: Bytes of rows :func:`mass_gram` weights at a time.
GRAM_BLOCK_BYTES = 16 * 2**20


def mass_gram(x: np.ndarray, mass: np.ndarray) -> np.ndarray:
    """
    Return ``x^T M x`` (symmetric) for a lumped mass ``mass`` and columns ``x``.

    In blocks of rows, so that no temporary the size of ``x`` is made (on a large scene ``x`` can
    be a stage's largest array).
    """
    out = np.zeros((x.shape[1], x.shape[1]))
    rows = max(1, GRAM_BLOCK_BYTES // max(8 * x.shape[1], 1))
    for start in range(0, x.shape[0], rows):
        block = x[start:start + rows]
        out += block.T @ (mass[start:start + rows, None] * block)
    return 0.5 * (out + out.T)

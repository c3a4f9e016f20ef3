"""The distinct rows of integer arrays: exactly what ``np.unique(axis=0)`` gives."""
from __future__ import annotations

from modal_spring_ros.core.model.integer_rows import unique_rows
import numpy as np
import pytest


@pytest.mark.parametrize('rows', [
    np.random.default_rng(0).integers(0, 50, size=(2000, 2)),            # edges, many repeated
    np.random.default_rng(1).integers(-7, 7, size=(500, 3)),              # rounded points
    np.random.default_rng(2).integers(0, 2 ** 40, size=(300, 2)),         # wide, still one key
    np.random.default_rng(3).integers(-2 ** 62, 2 ** 62, size=(300, 3)),  # too wide: numpy's way
    np.random.default_rng(4).integers(0, 9, size=(400, 4)).astype(np.int32),
    np.zeros((0, 3), dtype=np.int64)])
def test_unique_rows_are_numpy_s_with_every_return(rows):
    expected = np.unique(rows, axis=0, return_index=True, return_inverse=True,
                         return_counts=True)
    got = unique_rows(rows, return_index=True, return_inverse=True, return_counts=True)
    assert len(got) == 4
    for mine, theirs in zip(got, expected):
        assert np.array_equal(mine, np.ravel(theirs) if mine.ndim == 1 else theirs)
    assert np.array_equal(got[0][got[2]], rows)                            # the inverse rebuilds
    assert np.array_equal(unique_rows(rows), expected[0])
    (only, counts) = unique_rows(rows, return_counts=True)
    assert np.array_equal(counts, expected[3]) and counts.sum() == rows.shape[0]

"""The per-step benchmark's measurement builds every method it lists (timings are not asserted)."""
from __future__ import annotations

import math

from modal_spring_ros.bench.costs.steps import _measure
import pytest


@pytest.mark.parametrize('method, modes, refresh', [
    ('modal', 15, 1), ('modal', 15, 10), ('derivatives', 15, 1), ('full', None, 1)])
def test_each_method_of_the_step_benchmark_is_built_and_stepped(method, modes, refresh):
    row = _measure('sheet_10x10', method, modes, 5e-4, refresh, 2, 20)
    assert math.isfinite(row['step_us']) and row['step_us'] > 0.0
    assert row['basis_s'] >= 0.0

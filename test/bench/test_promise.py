"""The promise benchmark: one random scene planned, checked independently, summarised, drawn."""
from __future__ import annotations

from modal_spring_ros.bench import promise
import numpy as np
import pytest


@pytest.mark.slow
def test_one_random_scene_is_planned_checked_and_charted(tmp_path):
    row = promise.measure(seed=1, tolerance=0.01)
    assert row['refused'] == ''
    # the independent check: over 3 s against the converged full run, within 2 T
    assert 0.0 < row['achieved'] <= 0.02 and 0.0 < row['printed'] <= 0.01
    # the baseline is the full run at the longest step meeting T, timed in the same process
    assert row['full_error'] <= 0.01 and row['full_cpu_per_s'] > 0
    assert row['cost_ratio'] == pytest.approx(row['auto_cpu_per_s'] / row['full_cpu_per_s'])
    refused = dict(row, seed=2, refused='modal.auto cannot measure a plan for this scene')
    worse = dict(row, seed=3, achieved=0.015, cost_ratio=2.0)
    results = {'rows': [row, refused, worse],
               'summary': promise.summary([row, refused, worse])}
    (s,) = results['summary']
    assert (s['scenes'], s['refused']) == (3, 1)
    assert s['within_t'] == np.mean([row['achieved'] <= 0.01, False])
    assert s['within_2t'] == 1.0 and s['worst_ratio'] == pytest.approx(1.5)
    assert s['max_cost_ratio'] == 2.0
    assert '1.0%' in promise.table(results).splitlines()[1]
    promise.write_outputs(results, tmp_path, lambda msg: None)
    assert (tmp_path / 'promise.png').stat().st_size > 10_000
    assert len((tmp_path / 'promise.csv').read_text().splitlines()) == 4

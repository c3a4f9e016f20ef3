"""The headline suite: the README's figures over whole runs, each window checked on its own."""
from __future__ import annotations

import csv

from modal_spring_ros.bench.accuracy import headline
from modal_spring_ros.core.auto.measured_error import trajectory_error
import numpy as np
import pytest


def _row(run, duration, error, cpu, full_cpu=1.0):
    return {'run': run, 'duration_s': duration, 'coordinates': 10, 'dt': 1e-3, 'error': error,
            'cpu_per_s': cpu, 'ratio': full_cpu / cpu, 'forces': ''}


def test_a_figure_is_the_cheapest_run_within_the_tolerance_over_that_duration():
    sampled = f'{headline.SAMPLED_MODES} modes, sampled springs'
    results = {'tolerance': 0.01, 'durations_s': [1.0, 5.0], 'rows': [
        _row(sampled, 1.0, 0.009, 0.01), _row(sampled, 5.0, 0.013, 0.01),   # cheap, drifts out
        _row(sampled, 1.0, 0.004, 0.02), _row(sampled, 5.0, 0.006, 0.02),
        _row('auto', 1.0, 0.02, 0.05), _row('auto', 5.0, 0.02, 0.05)]}
    figures = {(f['duration_s'], f['run']): f for f in headline.figures(results)}
    assert figures[(1.0, sampled)]['ratio'] == pytest.approx(100.0)
    assert figures[(5.0, sampled)]['ratio'] == pytest.approx(50.0)   # the step that holds
    assert figures[(5.0, sampled)]['error'] == 0.006
    assert figures[(1.0, 'auto')]['ratio'] is None                   # none within: no figure
    assert 'none within the tolerance' in headline.table(
        dict(results, scene='s', particles=1, full_dt=1e-3, figures=headline.figures(results)))


def test_the_window_error_is_the_error_of_the_run_cut_to_that_window():
    rng = np.random.default_rng(3)
    reference = rng.normal(size=(50, 6))
    run = reference + 0.01 * np.arange(50)[:, None] * rng.normal(size=(50, 6))  # drifts
    short = headline._window_error(run, reference, 10)
    assert short == pytest.approx(trajectory_error(run[:10], reference[:10]))
    assert short < headline._window_error(run, reference, 50)
    assert headline._window_error(None, reference, 10) == float('inf')


@pytest.mark.slow
def test_measured_on_a_small_sheet_every_run_is_checked_over_every_duration(tmp_path):
    results = headline.measure('sheet_10x10', (0.1, 0.3), lambda msg: None)
    rows = results['rows']
    kinds = {r['run'] for r in rows}
    assert kinds == {'full', 'auto', f'{headline.SAMPLED_MODES} modes, sampled springs'}
    assert {r['duration_s'] for r in rows} == {0.1, 0.3}
    for r in rows:
        assert np.isfinite(r['error']) and r['cpu_per_s'] > 0
    for r in (r for r in rows if r['run'] == 'full'):
        # the baseline meets the tolerance over the longest run, so over every shorter one
        assert r['error'] <= headline.TOLERANCE and r['ratio'] == 1.0
    sampled = [r for r in rows if r['run'].endswith('sampled springs') and r['duration_s'] == 0.3]
    assert [r['dt'] for r in sampled] == pytest.approx(list(headline.SAMPLED_STEPS_S))
    assert 'sampled' in sampled[0]['forces']
    results['figures'] = headline.figures(results)
    headline.write_outputs(results, tmp_path, lambda msg: None)
    with open(tmp_path / 'headline.csv') as fh:
        assert len(list(csv.DictReader(fh))) == len(rows)

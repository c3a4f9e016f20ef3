"""
The response benchmark: requested against measured gains and damping, mode by mode.

What the filter documents, measured as the benchmark measures it: output gains exact to
round-off, load gains to 0.1 % where the drive reaches a mode (small motion: linear), damping
ratios within 5 %.
"""
from __future__ import annotations

from modal_spring_ros.bench.accuracy import response
import pytest


@pytest.fixture(scope='module')
def results():
    return response.run(quick=True, progress=lambda msg: None)


@pytest.mark.slow
def test_each_mode_s_measured_gain_and_damping_is_the_requested(results):
    summary = {s['case']: s for s in results['summary']}
    assert summary['output']['modes'] == 180
    assert summary['output']['worst_relative_error'] < 1e-12
    assert summary['load']['modes'] >= 60
    assert summary['load']['worst_relative_error'] < 1e-3     # linear: the requested gain
    assert summary['damping']['modes'] == 180
    assert summary['damping']['worst_relative_error'] < 0.05
    peak = max((r for r in results['rows'] if r['case'] == 'output'),
               key=lambda r: r['requested'])
    assert peak['requested'] > 2.0 and peak['measured'] == pytest.approx(peak['requested'])


def test_the_results_are_written_as_a_table_a_csv_and_a_chart(results, tmp_path):
    assert 'damping' in response.table(results)
    response.write_outputs(results, tmp_path, lambda msg: None)
    rows = (tmp_path / 'response.csv').read_text().splitlines()
    assert rows[0] == 'case,mode,hz,requested,measured' and len(rows) == len(results['rows']) + 1
    assert (tmp_path / 'response.png').read_bytes()[:4] == b'\x89PNG'

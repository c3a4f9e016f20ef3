"""
The watch benchmark: the shaken sheet's plan, unwatched and watched never due.

What the benchmark reports is what the watch did: the sentinel's window, the one that followed
while the error headed beyond the tolerance, the fallback within the quarter second the plan's
own error passes 2 T; written as a table, a CSV and a chart.
"""
from __future__ import annotations

from modal_spring_ros.bench.accuracy import watched
from modal_spring_ros.core.auto.watch.run_watch import HEADING
import pytest


@pytest.fixture(scope='module')
def results():
    return watched.run(quick=True, progress=lambda msg: None)


@pytest.mark.slow
def test_the_plan_is_caught_where_its_error_passes_twice_the_tolerance(results):
    first, caught = results['windows'][0], results['windows'][1]
    assert 'times the largest measured' in first['cause'] and first['within']
    assert first['rising'] and caught['cause'] == HEADING
    assert not caught['within'] and caught['run'] == 'modal'
    assert results['fell_back_s'] == caught['start_s']
    passes = results['passes_2t_s']
    assert passes > first['start_s'] and results['fell_back_s'] < passes + results['quarter_s']
    errors = results['quarter_errors']
    assert max(errors) > 10 * watched.TOLERANCE          # unwatched, the plan is far off
    trace = results['trace']
    assert len(trace['t']) == len(trace['displacement']) > 300


@pytest.mark.slow
def test_the_results_are_written_as_a_table_a_csv_and_a_chart(results, tmp_path):
    assert 'fell back at' in watched.table(results)
    watched.write_outputs(results, tmp_path, lambda msg: None)
    rows = (tmp_path / 'watch.csv').read_text().splitlines()
    assert rows[0] == ','.join(watched.FIELDS) and len(rows) == len(results['windows']) + 1
    assert (tmp_path / 'watch.png').read_bytes()[:4] == b'\x89PNG'

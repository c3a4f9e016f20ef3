"""The promise benchmark: one random scene planned, checked independently, summarised, drawn."""
from __future__ import annotations

import sys

from modal_spring_ros.bench.accuracy import promise
from modal_spring_ros.bench.accuracy import promise_demanding
from modal_spring_ros.bench.costs import cli_runs
from modal_spring_ros.runs.sample_cache import CACHE_ENV
import numpy as np
import pytest


@pytest.mark.slow
def test_one_random_scene_is_planned_checked_and_charted(tmp_path, monkeypatch):
    monkeypatch.setattr(cli_runs, 'REPEATS', 1)          # each process once (their median: below)
    row = promise.measure(seed=1, tolerance=0.01)
    assert row['refused'] == ''
    # the independent check: over 3 s against the converged full run, within 2 T
    assert 0.0 < row['achieved'] <= 0.02 and 0.0 < row['printed'] <= 0.01
    # the baselines: the full run at its default step and at the longest step meeting T,
    # timed in the same process; what auto costs is the whole run, planning included
    assert row['full_error'] <= 0.01 and row['full_cpu_per_s'] > 0
    assert row['cost_ratio'] == pytest.approx(row['auto_cpu_per_s'] / row['full_cpu_per_s'])
    assert row['auto_whole_s'] == pytest.approx(row['plan_cpu_s'] + 3.0 * row['auto_cpu_per_s'])
    assert row['whole_vs_default'] == pytest.approx(row['auto_whole_s'] / row['default_whole_s'])
    # and as processes: modal_spring_sim --auto and --method full, interpreter and imports
    # included (more than what they plan and step)
    assert row['process_auto_s'] > row['auto_whole_s']
    assert row['process_default_s'] > row['default_whole_s']
    assert row['process_vs_default'] == pytest.approx(row['process_auto_s']
                                                      / row['process_default_s'])
    assert row['default_error'] >= 0.0 and row['default_dt'] >= row['full_dt']
    # no window is better than the run's average
    assert row['default_window'] >= row['default_error'] * (1.0 - 1e-12)
    refused = dict(row, seed=2, refused='modal.auto cannot measure a plan for this scene')
    worse = dict(row, seed=3, achieved=0.015, cost_ratio=2.0, whole_vs_at_t=2.0,
                 whole_vs_default=3.0, default_error=0.0, default_window=0.0)
    # a default step within T over the run but not in every window keeps no promise
    windowed = dict(row, seed=4, whole_vs_default=9.0, default_error=0.0, default_window=0.05)
    results = {'rows': [row, refused, worse, windowed],
               'summary': promise.summary([row, refused, worse, windowed])}
    (s,) = results['summary']
    assert (s['scenes'], s['refused']) == (4, 1)
    assert s['within_t'] == np.mean([row['achieved'] <= 0.01, False, row['achieved'] <= 0.01])
    assert s['within_2t'] == 1.0 and s['worst_ratio'] == pytest.approx(1.5)
    assert s['max_cost_ratio'] == max(2.0, row['cost_ratio'])
    assert s['max_whole_vs_at_t'] == max(2.0, row['whole_vs_at_t'])
    # only where the full run at its default step meets T
    kept = row['default_error'] <= 0.01 and row['default_window'] <= 0.02
    assert s['max_whole_vs_default'] == max([3.0] + [row['whole_vs_default']] * kept)
    assert s['default_meets_t'] == 1 + kept
    assert s['within_1_2_of_default'] == int(kept and row['whole_vs_default'] <= 1.2)
    # ``worse`` keeps the row's process figures, and its default run keeps the promise
    in_line = row['process_vs_default'] <= 1.2
    assert s['process_within_1_2_of_default'] == int(kept and in_line) + int(in_line)
    assert s['max_process_vs_default'] == row['process_vs_default']
    assert '1.0%' in promise.table(results).splitlines()[1]
    promise.write_outputs(results, tmp_path, lambda msg: None)
    assert (tmp_path / 'promise.png').stat().st_size > 10_000
    assert len((tmp_path / 'promise.csv').read_text().splitlines()) == 5


def test_the_worst_window_is_the_error_of_the_window_that_misses_most():
    """
    50 samples of 0.02 s (1 s): four equal windows of 12-13 samples, the third one 10 % off.

    Equal windows: 0.25 s windows of 12 samples would leave a last one of 2 samples.
    """
    reference = np.ones((50, 3))
    run = reference.copy()
    run[26:38] *= 1.1                         # the third window (samples 26-37), exactly
    assert promise.worst_window(run, reference, 0.02) == pytest.approx(0.1)
    assert promise.trajectory_error(run, reference) == pytest.approx(0.1 * np.sqrt(12 / 50))
    run = reference.copy()
    run[26:38] *= 1.1
    run[37] = 1.0                             # 11 of the window's 12 samples off
    assert promise.worst_window(run, reference, 0.02) == pytest.approx(0.1 * np.sqrt(11 / 12))
    assert promise.worst_window(None, reference, 0.02) == np.inf


def test_the_demanding_suite_tabulates_every_run_and_its_windows(tmp_path):
    row = {'seed': 4, 'scene': 'demanding_4', 'kind': 'large sheet', 'particles': 5166,
           'duration_s': 31.0, 'tolerance': 0.01, 'refused': '', 'method': 'modal',
           'achieved': 0.004, 'printed': 0.005, 'worst_window': 0.03, 'cost_ratio': 0.2,
           'whole_vs_default': 0.4, 'whole_vs_at_t': 0.6, 'default_error': 0.002}
    refused = dict(row, seed=5, refused='the reference did not converge')
    results = {'rows': [row, refused], 'summary': promise.summary([row, refused])}
    (s,) = results['summary']
    assert s['within_t'] == 1.0 and s['windows_within_2t'] == 0.0   # 3 % in one window
    text = promise_demanding.table(results)
    assert '   4   large sheet      5166    31  1.0%  modal    0.40%    0.50%        3.00%' in text
    assert 'refused: the reference did not converge' in text
    promise_demanding.write_outputs(results, tmp_path, lambda msg: None)
    assert (tmp_path / 'promise_demanding.png').stat().st_size > 10_000


def test_the_demanding_suite_runs_the_seeds_a_user_lists(monkeypatch):
    """``--seeds 1-3,5``: those seeds, once each, in order; every other seed left alone."""
    assert promise_demanding.select_seeds('1-3,5') == [1, 2, 3, 5]
    assert promise_demanding.select_seeds(' 4 , 4,0-1') == [4, 0, 1]
    for bad, message in (('7', 'the seeds are 0 to 6'), ('3-1', 'each range ascending'),
                         ('a', "'a' is not a seed"), ('1-', "'1-' is not a seed"),
                         ('', "'' is not a seed")):
        with pytest.raises(ValueError, match=message):
            promise_demanding.select_seeds(bad)
    measured = []
    monkeypatch.setattr(promise, 'in_workers',
                        lambda measure, seeds, name, progress: measured.append(seeds) or {})
    promise_demanding.run(False, lambda msg: None, [1, 5])
    promise_demanding.run(True, lambda msg: None)
    assert measured == [[1, 5], list(range(promise_demanding.QUICK_SEEDS))]


def test_a_process_is_costed_by_its_cpu_time_and_a_failed_one_is_said(tmp_path):
    """A process spinning for a while costs that much CPU; one that fails names itself."""
    env = cli_runs.process_env(tmp_path)
    assert env['OPENBLAS_NUM_THREADS'] == '1' and str(tmp_path) in env[CACHE_ENV]
    spin = [sys.executable, '-c', 'import time\nt = time.process_time()\n'
            'while time.process_time() - t < 0.3: pass']
    assert 0.3 <= cli_runs.cpu_seconds(spin, env) < 3.0
    failing = [sys.executable, '-c', 'import sys; print("nope", file=sys.stderr); sys.exit(3)']
    with pytest.raises(RuntimeError, match='exited with 3: nope'):
        cli_runs.cpu_seconds(failing, env)


def test_a_process_cost_is_the_median_of_its_runs_each_with_a_cache_of_its_own(monkeypatch):
    """``--auto`` and ``--method full`` in turn, ``REPEATS`` times; nothing cached is shared."""
    ran = []
    seconds = iter([0.9, 0.7, 3.0, 0.8, 1.0, 5.0])                 # auto, full, auto, ...

    def cost(args, env):
        ran.append(('--auto' in args, env[CACHE_ENV]))
        return next(seconds)
    monkeypatch.setattr(cli_runs, 'cli_cpu_seconds', cost)
    monkeypatch.setattr(cli_runs, 'REPEATS', 3)
    scene = promise.random_scene(1, promise.MAX_PARTICLES)
    assert cli_runs.process_costs(scene, 0.01, 3.0) == (1.0, 0.8)  # medians, not the first
    assert [auto for auto, _ in ran] == [True, False] * 3
    assert len({cache for _, cache in ran}) == 6

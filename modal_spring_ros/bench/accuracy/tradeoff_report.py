"""
The trade-off suite's outputs: ``tradeoff.csv``, the charts, and the table printed at the end.

The results are :func:`modal_spring_ros.bench.accuracy.tradeoff.run`'s.
"""
from __future__ import annotations

import csv
from pathlib import Path

from modal_spring_ros.bench.charts import draw_all


def write_outputs(result: dict, out: Path, progress) -> None:
    fields = ['scene', 'method', 'modes', 'dt', 'stability_limit', 'rel_l2', 'max_err',
              'energy_drift', 'seconds_per_sim_second', 'cpu_seconds_per_sim_second',
              'seconds_per_step', 'diverged', 'note']
    with open(out / 'tradeoff.csv', 'w', newline='') as fh:
        w = csv.DictWriter(fh, fieldnames=fields, extrasaction='ignore')
        w.writeheader()
        for case in result['cases']:
            w.writerows(case['configs'])
    for path in draw_all(result, out):
        progress(f'chart {path}')


def table(result: dict) -> str:
    lines = []
    for case in result['cases']:
        lines.append(f"{case['scene']}: reference check {case['reference_check_rel_l2']:.1e}, "
                     f"peak memory {case['peak_memory_mb']:.0f} MB, median of "
                     f"{case['repeats']} timed run(s)")
        lines.append(f"  {'method':15s} {'modes':>5s} {'dt ms':>7s} {'rel L2':>9s} "
                     f"{'s/sim s':>9s} {'CPU s':>9s}")
        for r in case['configs']:
            cost, cpu = (f'{r[key]:.3g}' if r.get(key) else '-'
                         for key in ('seconds_per_sim_second', 'cpu_seconds_per_sim_second'))
            lines.append(f"  {r['method']:15s} {r['modes']:5d} {1e3 * r['dt']:7.3f} "
                         f"{r['rel_l2']:9.2e} {cost:>9s} {cpu:>9s}")
        t = case['cheapest_at_1pct']
        lines.append(f'  cheapest at 1 %: {t}')
    f = result['failure']
    lines.append(f"failure: error passes 10 % at {f['error_passes_10pct_at']} s, strain "
                 f"warning at {f['strain_warning_at']} s; with derivatives "
                 f"({f['derivatives_coordinates']} coordinates) the largest window is "
                 f"{max(f['derivatives_rel_l2_window']):.2%}, {f['derivatives_rel_l2']:.2%} over "
                 'the run')
    c = result['turning_clamp']
    cost = c['seconds_per_step']
    lines.append(f'turning clamp (sheet_10x10_swing, 15 modes): derivatives '
                 f"{c['rel_l2']['derivatives']:.3%}, rest modes {c['rel_l2']['rest']:.2%} in the "
                 f"clamp's frame; turn left out {c['rel_l2']['turn left out']:.0%} (world); "
                 f"step {1e6 * cost['sheet_10x10_swing']:.0f} us, "
                 f"{cost['sheet_10x10_swing'] / cost['sheet_10x10']:.2f} x the translating "
                 "sheet's")
    return '\n'.join(lines)

"""PNG charts of the trade-off benchmark (matplotlib, no display needed)."""
from __future__ import annotations

import math
from pathlib import Path

from matplotlib.figure import Figure
from modal_spring_ros.bench.accuracy.analysis import pareto

COLORS = {'full explicit': 'C3', 'full average': 'C1', 'modal explicit': 'C0',
          'modal refreshed': 'C4', 'modal average': 'C2', 'modal auto': 'k',
          'modal derivatives': 'C6', 'modal sampled': 'C9'}


def subplots(*grid, **kw):
    """
    Return a figure and its axes, without pyplot (no display, no global state).

    Figure.savefig renders with Agg.
    """
    figsize = kw.pop('figsize', None)
    fig = Figure(figsize=figsize)
    return fig, fig.subplots(*grid, **kw)


def finish_chart(fig, ax, path: Path, xlabel: str, ylabel: str, title: str, log: bool = True,
                 legend: bool = True) -> Path:
    """Label, scale (log-log unless ``log`` is False), lay out and save a chart at ``path``."""
    if log:
        ax.set_xscale('log')
        ax.set_yscale('log')
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    if legend:
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path


def _finite(rows):
    return [r for r in rows if r['seconds_per_sim_second'] and math.isfinite(r['rel_l2'])
            and r['rel_l2'] > 0]


def error_vs_cost(case: dict, path: Path) -> Path:
    fig, ax = subplots(figsize=(8, 5.5))
    rows = _finite(case['configs'])
    for method, color in COLORS.items():
        pts = sorted((r for r in rows if r['method'] == method),
                     key=lambda r: r['seconds_per_sim_second'])
        if not pts:
            continue
        marker = '*' if method == 'modal auto' else 'o'
        ax.scatter([r['seconds_per_sim_second'] for r in pts], [r['rel_l2'] for r in pts],
                   c=color, marker=marker, s=140 if marker == '*' else 30, label=method,
                   zorder=3)
    front = pareto(case['configs'])
    ax.step([r['seconds_per_sim_second'] for r in front], [r['rel_l2'] for r in front],
            where='post', color='0.4', lw=1, ls='--', label='Pareto front', zorder=2)
    ax.axhline(0.01, color='0.7', lw=0.8)
    return finish_chart(fig, ax, path, 'cost: wall seconds per simulated second',
                        'relative L2 displacement error',
                        f"{case['scene']}: error against cost ({case['free_dof']} DOF)")


def stability_map(case: dict, path: Path) -> Path:
    fig, ax = subplots(figsize=(7, 4.5))
    st = case['stability']
    modal = sorted((s for s in st if s['method'] == 'modal explicit'), key=lambda s: s['modes'])
    ax.plot([s['modes'] for s in modal], [s['largest_stable'] for s in modal], 'o-',
            label='modal explicit: largest stable step')
    ax.plot([s['modes'] for s in modal], [s['theory'] for s in modal], 'k--',
            label='2 / omega_max of the kept modes')
    derived = sorted((s for s in st if s['method'] == 'modal derivatives'),
                     key=lambda s: s['modes'])
    if derived:
        ax.plot([s['modes'] for s in derived], [s['largest_stable'] for s in derived], 's-',
                c='C6', label='modal derivatives: largest stable step')
        ax.plot([s['modes'] for s in derived], [s['theory'] for s in derived], ':', c='C6',
                label='2 / omega_max of the modes and their added coordinates')
    for s in st:
        if s['method'] == 'modal average':
            ax.scatter([s['modes']], [s['largest_stable']], marker='^', c='C2', zorder=3)
    ax.scatter([], [], marker='^', c='C2', label='modal average (tested up to 100x)')
    full = next(s for s in st if s['method'] == 'full explicit')
    ax.axhline(full['largest_stable'], color='C3', label='full explicit: largest stable step')
    return finish_chart(fig, ax, path, 'kept modes', 'time step (s)',
                        f"{case['scene']}: stability map")


def fig7(costs: dict, path: Path) -> Path:
    rows = costs['fig7']
    fig, ax = subplots(figsize=(6, 4))
    n = [r['particles'] for r in rows]
    ax.plot(n, [1e6 * r['full'] for r in rows], 'o-', c='C3', label='physical (full)')
    for key, colour, label in (('modal_exact', 'C0', '32 modes, every spring (the paper)'),
                               ('modal_refreshed', 'C2', '32 modes, springs every 10 steps'),
                               ('modal_sampled', 'C6', '32 modes, sampled springs')):
        if key in rows[0]:
            ax.plot(n, [1e6 * r[key] for r in rows], 'o-', c=colour, label=label)
    return finish_chart(fig, ax, path, 'particles', 'time per step (us)',
                        'Paper fig. 7 extended: time per step against particle count')


def fig8(costs: dict, path: Path) -> Path:
    rows = costs['fig8']
    fig, ax = subplots(figsize=(6, 4))
    ax.plot([r['dropped'] for r in rows], [1e6 * r['seconds_per_step'] for r in rows], 'o-')
    return finish_chart(fig, ax, path, 'dropped modes (of 180)', 'time per step (us)',
                        'Paper fig. 8: sheet_10x10, time per step against dropped modes',
                        log=False, legend=False)


def failure_chart(f: dict, path: Path) -> Path:
    fig, (top, bottom) = subplots(2, 1, figsize=(8, 6.5), sharex=True)
    top.semilogy(f['t'], f['rel_l2_window'],
                 label='15 rest modes (the paper) against full (0.25 s windows)')
    if 'derivatives_rel_l2_window' in f:
        top.semilogy(f['t'], f['derivatives_rel_l2_window'], c='C6',
                     label='15 modes + derivatives against full')
    top.axhline(0.1, color='0.6', ls='--', lw=0.8)
    if f['error_passes_10pct_at'] is not None:
        top.axvline(f['error_passes_10pct_at'], color='C3',
                    label=f"error passes 10 % at {f['error_passes_10pct_at']:.2f} s")
    top.set_ylabel('relative L2 error')
    top.set_title('Where rest modes fail, and derivatives hold: sheet_10x10_resonance')
    top.legend(fontsize=8)
    bottom.plot(f['t'], f['modal_strain'], label='modal run: largest spring strain')
    bottom.plot(f['t'], f['full_strain'], label='full run: largest spring strain', alpha=0.7)
    bottom.axhline(f['strain_warning'], color='C1', ls='--',
                   label="node's strain warning (sim.strain_warning)")
    if f['strain_warning_at'] is not None:
        bottom.axvline(f['strain_warning_at'], color='C1',
                       label=('node reports WARN on /diagnostics at '
                              f"{f['strain_warning_at']:.2f} s"))
    bottom.set_xlabel('time (s)')
    bottom.set_ylabel('strain')
    bottom.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path


def turning_clamp_chart(f: dict, path: Path) -> Path:
    fig, ax = subplots(figsize=(8, 4.2))
    w = f['windows']
    ax.semilogy(f['t'], w['rest'], label="15 rest modes in the clamp's frame")
    ax.semilogy(f['t'], w['derivatives'], c='C6',
                label=f"15 modes + derivatives in the clamp's frame ({f['coordinates']} coord.)")
    ax.semilogy(f['t'], w['turn left out'], c='C3', ls='--',
                label='turn left out (base excitation only): world positions')
    ax.axhline(0.02, color='0.6', ls=':', lw=0.8)
    ax.legend(fontsize=8, loc='center right')
    return finish_chart(fig, ax, path, 'time (s)', 'relative L2 error (0.25 s windows)',
                        'A clamp turning +-45 degrees at 0.5 Hz: sheet_10x10_swing against full',
                        log=False, legend=False)


def draw_all(result: dict, out: Path) -> list[Path]:
    paths = []
    for case in result['cases']:
        paths.append(error_vs_cost(case, out / f"error_vs_cost_{case['scene']}.png"))
        paths.append(stability_map(case, out / f"stability_{case['scene']}.png"))
    paths.append(fig7(result['step_costs'], out / 'fig7_time_per_step_vs_particles.png'))
    paths.append(fig8(result['step_costs'], out / 'fig8_time_per_step_vs_dropped_modes.png'))
    paths.append(failure_chart(result['failure'], out / 'large_deformation_failure.png'))
    if 'turning_clamp' in result:
        paths.append(turning_clamp_chart(result['turning_clamp'], out / 'turning_clamp.png'))
    return paths

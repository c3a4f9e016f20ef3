"""
Speed against accuracy, stability where methods fail, and the automatic mode choice.

For each scene, every configuration (method x kept modes x time step) runs the same simulated
time, sampled every ``SAMPLE_S``; its error is measured against a converged reference (the
full nonlinear physics with explicit Newmark at a small fraction of its stability limit; the
run at twice that step is compared with it to show it converged), and its cost is the wall
time per simulated second. The largest stable step of each method is found by bisection
from a broadband-perturbed state. Results go to ``tradeoff.json``/``tradeoff.csv``;
:mod:`modal_spring_ros.bench.charts` draws them.
"""
from __future__ import annotations

import dataclasses
import math
import resource
import time
from typing import Callable

from modal_spring_ros.bench.accuracy.analysis import cheapest_reaching, pareto
from modal_spring_ros.bench.accuracy.failure import failure, turning_clamp
# the suite's outputs (the bench command calls each suite's run, table and write_outputs)
from modal_spring_ros.bench.accuracy.tradeoff_report import table, write_outputs  # noqa: F401
from modal_spring_ros.bench.child_run import in_child
from modal_spring_ros.core.bases.basis import ModalBasis
from modal_spring_ros.core.bases.derivatives import DEFAULT_DIRECTIONS
from modal_spring_ros.core.bases.mode_selection import choose_modes, choose_refresh, choose_step
from modal_spring_ros.core.config import DEFAULT_REFRESH
from modal_spring_ros.core.factory import force_options
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.forces import ForceOptions
from modal_spring_ros.core.integrators import stable_step
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.simulations import (DivergenceError, FullSimulation, ModalSettings,
                                               ModalSimulation, Simulation)
from modal_spring_ros.core.simulations.coordinates import AddedCoordinateBank
from modal_spring_ros.core.threads import stepping_threads
from modal_spring_ros.runs.sample_cache import sample_cache
from modal_spring_ros.scenes.resources import load_scene
import numpy as np

SAMPLE_S = 0.01
METHODS = ('full explicit', 'full average', 'modal explicit', 'modal refreshed',
           'modal average', 'modal auto', 'modal derivatives', 'modal sampled')


@dataclasses.dataclass
class Case:
    scene: str
    duration: float
    modal_counts: tuple[int, ...]
    average_counts: tuple[int, ...]
    average_divisors: tuple[int, ...]
    stability_counts: tuple[int, ...]
    reference_fraction: float = 1.0 / 16   # reference step, as a fraction of the limit
    repeats: int = 3                        # timed runs per configuration (median)


QUICK = [Case('sheet_10x10', 1.0, (2, 4, 8, 16, 32, 64, 180), (4, 16), (1, 2, 4),
              (2, 8, 32, 180), repeats=1)]
FULL = [
    Case('sheet_10x10', 2.0, (2, 4, 8, 16, 32, 64, 180), (4, 16, 64), (1, 2, 4, 8),
         (2, 4, 8, 16, 32, 64, 128, 180)),
    Case('sheet_32x32', 1.0, (2, 4, 8, 16, 32, 64), (4, 16), (1, 2, 4), (2, 8, 32, 64)),
    Case('sheet_100x100', 0.5, (4, 8, 16, 32), (16,), (1, 2, 4, 8), (4, 16, 32), 1.0 / 8, 1),
]


def _divisor(dt: float) -> int:
    """Smallest n with SAMPLE_S / n <= dt (steps land on the sample grid)."""
    return max(1, math.ceil(SAMPLE_S / dt - 1e-9))


@stepping_threads()         # as the node and modal_spring_sim step (core.threads)
def _run(sim: Simulation, duration: float, repeats: int = 1) -> dict:
    """
    Step ``sim`` for ``duration`` (after a warm-up), ``repeats`` times from rest.

    Samples of the relative displacement from the last run, and the median wall time of stepping
    and reading the displacement (the energy, a measurement, is not timed), with the CPU time the
    process burnt meanwhile (every thread: what a busy machine pays).
    """
    per = int(round(SAMPLE_S / sim.dt))
    samples = int(round(duration / SAMPLE_S))
    out = np.empty((samples, sim.model.n_free_dof))
    energy = np.empty(samples)
    sim.step(min(per, 20))  # warm-up (caches, first allocations)
    walls, cpus = [], []
    for _ in range(repeats):
        sim.reset()
        wall = cpu = 0.0
        try:
            for k in range(samples):
                start, start_cpu = time.perf_counter(), time.process_time()
                sim.step(per)
                out[k] = sim.displacement()
                wall += time.perf_counter() - start
                cpu += time.process_time() - start_cpu
                energy[k] = sim.energy()['total']  # a measurement, not part of the cost
        except DivergenceError as exc:
            return {'diverged': str(exc), 'wall': wall}
        walls.append(wall)
        cpus.append(cpu)
    return {'u': out, 'energy': energy, 'wall': float(np.median(walls)),
            'cpu': float(np.median(cpus)), 'steps': samples * per}


def _errors(run: dict, ref: dict) -> dict:
    if 'diverged' in run:
        return {'rel_l2': math.inf, 'max_err': math.inf, 'energy_drift': math.inf}
    diff = run['u'] - ref['u']
    return {'rel_l2': float(np.linalg.norm(diff) / np.linalg.norm(ref['u'])),
            'max_err': float(np.abs(diff).max()),
            'energy_drift': float(np.abs(run['energy'] - ref['energy']).max()
                                  / max(np.ptp(ref['energy']), 1e-300))}


def _stable(make: Callable[[float], Simulation], dt: float, u0: np.ndarray) -> bool:
    sim = make(dt)
    sim.set_state(u0, np.zeros_like(u0))
    try:
        sim.step(300)
    except DivergenceError:
        return False
    return bool(np.abs(sim.displacement()).max() < 100 * max(np.abs(u0).max(), 1e-3))


def largest_stable_step(make: Callable[[float], Simulation], lo: float, hi: float,
                        u0: np.ndarray, iterations: int = 10) -> float:
    """Bisection (on a log scale) between a stable ``lo`` and ``hi``; ``hi`` if it is stable."""
    if _stable(make, hi, u0):
        return hi
    for _ in range(iterations):
        mid = math.sqrt(lo * hi)
        if _stable(make, mid, u0):
            lo = mid
        else:
            hi = mid
    return lo


def run_case(case: Case, progress: Callable[[str], None]) -> dict:
    model = MassSpringModel(load_scene(case.scene))
    top = max(case.modal_counts + case.stability_counts)
    basis = ModalBasis(model, initial_modes=min(top, model.n_free_dof - 2),
                       samples=sample_cache())
    omega_max = basis.omega_max_estimate()
    limit = stable_step('explicit', omega_max)

    def full(dt, integrator='explicit'):
        return FullSimulation(model, dt=dt, integrator=integrator, basis=basis)

    banks: dict[int, AddedCoordinateBank] = {}  # each band's derivatives, computed once

    def modal(count, dt, integrator='explicit', refresh=1, basis_kind='rest', sampled=False):
        bank = banks.setdefault(count, AddedCoordinateBank(basis, DEFAULT_DIRECTIONS)) \
            if basis_kind == 'derivatives' else None
        forces = force_options('sampled' if sampled else 'exact', refresh, SAMPLE_TOLERANCE)
        return ModalSimulation(model, basis, FilterBand('lowpass', 0, count - 1, 'index'),
                               ModalSettings(dt=dt, integrator=integrator, forces=forces,
                                             basis_kind=basis_kind), bank=bank)

    def refresh(count, dt):
        return choose_refresh(float(basis.frequencies_hz[count - 1]), dt)

    progress(f'{case.scene}: reference (full explicit at '
             f'1/{round(1 / case.reference_fraction)} of its limit, and at twice that step)')
    n_ref = 2 * _divisor(2 * case.reference_fraction * limit)
    ref = _run(full(SAMPLE_S / n_ref), case.duration)
    check = _run(full(2 * SAMPLE_S / n_ref), case.duration)
    ref_check = _errors(check, ref)['rel_l2']   # the reference's error is about a third
    configs = []

    def add(method, sim, modes, note=''):
        progress(f'{case.scene}: {method}, {modes} modes, dt {sim.dt:.3g} s {note}')
        r = _run(sim, case.duration, case.repeats)
        row = {'scene': case.scene, 'method': method, 'modes': modes, 'dt': sim.dt,
               'stability_limit': sim.stability_limit(), **_errors(r, ref),
               'seconds_per_sim_second': r['wall'] / case.duration if 'steps' in r else None,
               'seconds_per_step': r['wall'] / r['steps'] if 'steps' in r else None,
               'cpu_seconds_per_sim_second': r['cpu'] / case.duration if 'steps' in r else None,
               'diverged': r.get('diverged', ''), 'note': note}
        configs.append(row)
        return row

    n_full = _divisor(0.95 * limit)
    for n in (n_full, 2 * n_full):
        add('full explicit', full(SAMPLE_S / n), model.n_free_dof)
    for n in case.average_divisors:
        add('full average', full(SAMPLE_S / n, 'average'), model.n_free_dof)
    for count in case.modal_counts:
        if count > basis.count and not basis.complete:
            basis.ensure_count(count)
        count = min(count, basis.count)
        n = _divisor(0.95 * stable_step('explicit', basis.omega[count - 1]))
        for k in (n, 2 * n, 4 * n):
            add('modal explicit', modal(count, SAMPLE_S / k), count)
            every = refresh(count, SAMPLE_S / k)
            if every > 1:
                add('modal refreshed', modal(count, SAMPLE_S / k, refresh=every), count,
                    f'springs every {every} steps')
            if count < model.n_free_dof:   # trained once per band (cached), then reused
                sampled = modal(count, SAMPLE_S / k, sampled=True)
                add('modal sampled', sampled, count, sampled.force_report().description)
        if count < model.n_free_dof:   # the band's derivatives: their own stability limit
            probe = modal(count, SAMPLE_S, basis_kind='derivatives')
            n = _divisor(0.95 * probe.stability_limit())
            for k in (n, 2 * n):
                add('modal derivatives', modal(count, SAMPLE_S / k, basis_kind='derivatives'),
                    count, f'+ {probe.coordinates - count} derivative and static coordinates')
    for count in case.average_counts:
        for n in case.average_divisors:
            add('modal average', modal(count, SAMPLE_S / n, 'average'), count)
    for tol in (0.05, 0.01):
        choice = choose_modes(model, basis, tolerance=tol)
        dt = choose_step(choice, 'explicit', tol, model.scene.damping)
        dt = SAMPLE_S / _divisor(dt)
        every = choose_refresh(choice.highest_hz, dt)
        add('modal auto', modal(choice.count, dt, refresh=every), choice.count,
            f'tolerance {tol:g}: {choice.describe()}, springs every {every} steps').update(
            predicted_error=choice.predicted_error, tolerance=tol)
        add('modal explicit', modal(choice.count, dt), choice.count,
            f'the automatic choice at tolerance {tol:g} with the springs every step (paper)')

    progress(f'{case.scene}: stability limits (bisection)')
    rng = np.random.default_rng(7)
    u0 = basis.vectors @ rng.normal(scale=1e-4, size=basis.count)  # every computed mode
    stability = [{'method': 'full explicit', 'modes': model.n_free_dof,
                  'theory': limit, 'largest_stable': largest_stable_step(
                      lambda dt: full(dt), 0.5 * limit, 2.0 * limit, u0)}]
    for count in case.stability_counts:
        count = min(count, basis.count)
        theory = stable_step('explicit', basis.omega[count - 1])
        stability.append({'method': 'modal explicit', 'modes': count, 'theory': theory,
                          'largest_stable': largest_stable_step(
                              lambda dt, c=count: modal(c, dt), 0.5 * theory, 2.0 * theory,
                              u0)})
    for count in case.stability_counts:
        count = min(count, basis.count)
        if count >= model.n_free_dof:
            continue
        theory = modal(count, SAMPLE_S, basis_kind='derivatives').stability_limit()
        stability.append({'method': 'modal derivatives', 'modes': count, 'theory': theory,
                          'largest_stable': largest_stable_step(
                              lambda dt, c=count: modal(c, dt, basis_kind='derivatives'),
                              0.5 * theory, 2.0 * theory, u0)})
    for count in (case.stability_counts[0], case.stability_counts[-1]):
        count = min(count, basis.count)
        stability.append({'method': 'modal average', 'modes': count,
                          'theory': math.inf, 'largest_stable': largest_stable_step(
                              lambda dt, c=count: modal(c, dt, 'average'), limit,
                              100 * limit, u0, iterations=6)})
    return {'scene': case.scene, 'particles': model.scene.n_particles,
            'free_dof': model.n_free_dof, 'duration': case.duration, 'repeats': case.repeats,
            'peak_memory_mb': resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
            'omega_max': omega_max, 'reference_dt': SAMPLE_S / n_ref,
            'reference_check_rel_l2': ref_check, 'configs': configs, 'stability': stability}


#: the band of the extended fig. 7
FIG7_MODES = 32
#: relative force error the sampled springs are trained to keep
SAMPLE_TOLERANCE = 0.01


def step_costs(scenes: list[str], dropped: list[int], progress) -> dict:
    """
    Return the paper's figs.

    7 and 8, extended: time per step against particle count (full, and a 32-mode band with exact,
    refreshed and sampled spring forces), and of sheet_10x10 against the number of dropped modes
    (medians of repeated batches).
    """
    def per_step(sim, steps):
        sim.step(steps)
        times = []
        for _ in range(5):
            t0 = time.perf_counter()
            sim.step(steps)
            times.append((time.perf_counter() - t0) / steps)
        return float(np.median(times))

    fig7 = []
    band = FilterBand('lowpass', 0, FIG7_MODES - 1, 'index')
    for name in scenes:
        progress(f'fig. 7: {name}')
        model = MassSpringModel(load_scene(name))
        basis = ModalBasis(model, initial_modes=FIG7_MODES, progress=progress,
                           samples=sample_cache())
        steps = max(20, 4000 // max(1, model.scene.n_particles // 25))
        row = {'scene': name, 'particles': model.scene.n_particles,
               'springs': model.scene.n_springs,
               'full': per_step(FullSimulation(model, dt=1e-5, basis=basis), steps)}
        for label, options in (('modal_exact', {}),
                               ('modal_refreshed', {'forces': ForceOptions(
                                   'refreshed', DEFAULT_REFRESH)}),
                               ('modal_sampled', {'forces': ForceOptions('sampled',
                                                                         tolerance=0.01)})):
            sim = ModalSimulation(model, basis, band,
                                  ModalSettings(dt=1e-4, basis_kind='rest', **options))
            row[label] = per_step(sim, max(steps, 200))
            if label == 'modal_sampled':
                row['sampled_springs'] = sim._forces.sample.count
                row['sample_seconds'] = sim._forces.sample.seconds
        fig7.append(row)
    progress('fig. 8: sheet_10x10, dropped modes')
    model = MassSpringModel(load_scene('sheet_10x10'))
    basis = ModalBasis(model)
    fig8 = [{'dropped': d, 'seconds_per_step': per_step(ModalSimulation(
        model, basis, FilterBand('lowpass', 0, 179 - d, 'index'), ModalSettings(dt=1e-4)), 500)}
        for d in dropped]
    return {'fig7': fig7, 'fig8': fig8}


def run_case_isolated(case: Case, progress: Callable[[str], None]) -> dict:
    """:func:`run_case` in its own process, so that its peak memory is the scene's own."""
    return in_child(run_case, case, what=f'tradeoff {case.scene}', progress=progress)


def run(quick: bool, progress: Callable[[str], None]) -> dict:
    cases = QUICK if quick else FULL
    result = {'quick': quick, 'sample_s': SAMPLE_S,
              'cases': [run_case_isolated(c, progress) for c in cases]}
    for case in result['cases']:
        rows = case['configs']
        case['pareto'] = [(r['method'], r['modes'], r['dt']) for r in pareto(rows)]
        for auto in (r for r in rows if r['method'] == 'modal auto'):
            best = cheapest_reaching(rows, auto['rel_l2'], METHODS)
            auto['cheapest_same_error'] = best['seconds_per_sim_second'] if best else None
            auto['cost_ratio_to_cheapest'] = (auto['seconds_per_sim_second']
                                              / best['seconds_per_sim_second']) if best else None
        targets = {}
        for name, methods in (('full explicit', ('full explicit',)),
                              ('full average', ('full average',)),
                              ('modal auto', ('modal auto',)),
                              ('modal, springs every step', ('modal explicit',
                                                             'modal average')),
                              ('modal (any)', ('modal explicit', 'modal refreshed',
                                               'modal average', 'modal auto'))):
            best = cheapest_reaching(rows, 0.01, methods)
            targets[name] = best['seconds_per_sim_second'] if best else None
        case['cheapest_at_1pct'] = targets
    result['step_costs'] = step_costs(['sheet_10x10', 'sheet_32x32'] if quick else
                                      ['sheet_10x10', 'sheet_32x32', 'sheet_100x100',
                                       'sheet_316x316'],
                                      list(range(0, 180, 45 if quick else 15)), progress)
    result['failure'] = failure(progress, 2.5 if quick else 6.0)
    result['turning_clamp'] = turning_clamp(progress, 3.0 if quick else 10.0)
    return result

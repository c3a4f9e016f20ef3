"""
Contact beside a peer: a sheet lowered onto a sphere and onto a table, and Newton doing the same.

Two scenes made here (:func:`lowered_sheet`): a 0.44 m square sheet of 12 x 12 particles (200 g,
springs of 200 N/m along its edges and diagonals, no bending: Newton's springs are the same object)
held flat by its four corners, sagging as it hangs, lowered 6 cm in its first second onto a sphere
of 8 cm radius under its middle or onto a table, each 2 cm below its lowest particle, with friction
0.4: the sphere lifts its middle, the table flattens it. (A curtain lowered onto them folds, a
bifurcation no step converges: its full run differed by 3-6 % at every halving of the step.) Over
that second, every run is checked as the peer suite checks one
(:mod:`~modal_spring_ros.bench.peers.peer`): the relative L2 error of the displacement against the
full run converged in its step, and its CPU seconds per simulated second, one after the other in
one process with one BLAS thread:

- ``full``: the project's full explicit run at the longest step that meets the tolerance;
- ``auto``: ``--auto --tolerance 0.01`` planned for the second (unbudgeted, as the peer suite);
- ``N modes + derivatives``: a fixed band, with the colliders, and ``... without colliders``: the
  same run of the same scene with its contact left out, costed only (it misses the touch by
  design), so that the ratio says what contact costs a modal run; the same for ``full``;
- ``newton``: Newton's ``SolverSemiImplicit`` with its particle-shape contact set as the
  project's (:mod:`~modal_spring_ros.bench.peers.newton_contact`), from 0.9 of the stability
  limit down by halves until it meets the tolerance.

Results: ``contact.json``, ``contact.csv`` and ``contact.png`` (error against cost).
"""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Callable

from modal_spring_ros.bench.accuracy.promise import converged_reference, cpu_per_second
from modal_spring_ros.bench.peers import newton_peer
from modal_spring_ros.bench.peers.peer import figure, peer_rows
from modal_spring_ros.bench.peers.peer import table as peer_table
from modal_spring_ros.bench.peers.peer import write_outputs as peer_outputs
from modal_spring_ros.core.auto.measured_error import on_samples, trajectory, trajectory_error
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.model.scene import Scene
from modal_spring_ros.core.threads import stepping_threads
from modal_spring_ros.scenes.schema import scene_from_dict

COLLIDERS = ('sphere', 'table')
TOLERANCE = 0.01
SAMPLE_S = 0.01
DURATION_S, QUICK_DURATION_S = 1.0, 0.5
#: the fixed bands (lowest N rest modes, with their derivatives) run with and without colliders
BANDS, QUICK_BANDS = (16, 32), (16,)
#: the sheet: particles along a side, their spacing (m), mass (kg), springs' stiffness (N/m)
COUNT, SPACING, MASS, STIFFNESS = 12, 0.04, 0.2, 200.0
#: how far it is lowered in its first second, and the collider's clearance below it, m
LOWERED, CLEARANCE = 0.06, 0.02
SPHERE_RADIUS, FRICTION = 0.08, 0.4


def lowered_sheet(collider: str) -> Scene:
    """Return the sheet held by its corners, lowered onto ``collider`` (sphere, table)."""
    data = {
        'name': f'sheet_onto_{collider}', 'dimension': 3,
        'particles': {'lattice': {'counts': [COUNT, COUNT, 1], 'spacing': SPACING},
                      'mass': MASS / COUNT ** 2},
        'springs': {'connect': ['edges', 'diagonals'], 'stiffness': STIFFNESS},
        'fixed': {'indices': [0, COUNT - 1, COUNT * COUNT - COUNT, COUNT * COUNT - 1]},
        'gravity': [0.0, 0.0, -9.81], 'damping': {'rayleigh': {'alpha': 0.5}},
        'anchor_motion': [   # down over a quarter period of 0.25 Hz: at its lowest at 1 s
            {'axis': 'z', 'amplitude': LOWERED, 'frequency_hz': 0.25, 'phase': math.pi,
             'ramp_s': 0.3}],
        'simulation': {'duration': DURATION_S}}
    hanging = scene_from_dict(data, source='contact benchmark')      # the shape it sags in
    x = hanging.rest_positions[~hanging.fixed]
    low = float(x[:, 2].min()) - CLEARANCE
    middle = x[:, :2].mean(axis=0).tolist()
    shape = ({'shape': 'sphere', 'center': [*middle, low - SPHERE_RADIUS],
              'radius': SPHERE_RADIUS} if collider == 'sphere'
             else {'shape': 'plane', 'point': [0.0, 0.0, low], 'normal': [0.0, 0.0, 1.0]})
    return scene_from_dict({**data, 'contact': {'friction': FRICTION, 'colliders': [shape]}},
                           source='contact benchmark')


def _row(run: str, coordinates: int, dt: float, error: float, cpu: float) -> dict:
    return {'run': run, 'coordinates': int(coordinates), 'dt': float(dt), 'error': error,
            'cpu_per_s': cpu}


@stepping_threads()         # one BLAS thread, as the node and modal_spring_sim step
def measure(collider: str, duration: float, bands: tuple[int, ...],
            progress: Callable[[str], None]) -> dict:
    """Return every run's error and cost on the sheet lowered onto ``collider``."""
    scene = lowered_sheet(collider)
    free = dataclasses.replace(scene, contact=None)
    samples = int(round(duration / SAMPLE_S))
    reference, full, full_error = converged_reference(scene, SAMPLE_S, samples, TOLERANCE,
                                                      progress)
    rows = [_row('full', full.coordinates, full.dt, full_error, cpu_per_second(full, duration))]
    bare = build_simulation(free, SimulationConfig(method='full', dt=full.dt))
    rows.append(_row('full, without colliders', bare.coordinates, bare.dt, math.nan,
                     cpu_per_second(bare, duration)))

    def ours(name: str, config: SimulationConfig) -> None:
        progress(f'{scene.name}: {name}')
        sim = on_samples(build_simulation(scene, config), SAMPLE_S)
        error = trajectory_error(trajectory(sim, SAMPLE_S, samples), reference)
        rows.append(_row(name, sim.coordinates, sim.dt, error,
                         cpu_per_second(sim, duration) if math.isfinite(error) else math.nan))

    ours('auto', SimulationConfig(auto=True, tolerance=TOLERANCE, horizon_s=duration,
                                  planning_share=None))
    for count in bands:
        config = SimulationConfig(band=FilterBand('lowpass', 0, count - 1, 'index'),
                                  basis='derivatives')
        ours(f'{count} modes + derivatives', config)
        sim = build_simulation(free, config)
        rows.append(_row(f'{count} modes + derivatives, without colliders', sim.coordinates,
                         sim.dt, math.nan, cpu_per_second(sim, duration)))
    refused = newton_peer.refusal(scene) if newton_peer.AVAILABLE else newton_peer.MISSING
    if not refused:
        rows += peer_rows(scene, reference, samples, full.stability_limit(), duration, progress)
    return {'scene': scene.name, 'particles': scene.n_particles, 'duration_s': duration,
            'tolerance': TOLERANCE, 'peer': '' if refused else 'newton', 'peer_note': refused,
            'rows': rows, 'figure': figure(rows), 'contact_cost': contact_cost(rows)}


def contact_cost(rows: list[dict]) -> dict[str, float]:
    """Return each run's CPU with its colliders over the same run's without them."""
    by_name = {r['run']: r['cpu_per_s'] for r in rows}
    suffix = ', without colliders'
    return {name[:-len(suffix)]: by_name[name[:-len(suffix)]] / cpu
            for name, cpu in by_name.items()
            if name.endswith(suffix) and name[:-len(suffix)] in by_name and cpu > 0}


def run(quick: bool, progress: Callable[[str], None]) -> dict:
    duration, bands = (QUICK_DURATION_S, QUICK_BANDS) if quick else (DURATION_S, BANDS)
    return {'scenes': [measure(c, duration, bands, progress) for c in COLLIDERS]}


def table(results: dict) -> str:
    return peer_table(results, lambda res: [
        f'  contact costs {name} {ratio:.2f}x its run without colliders'
        for name, ratio in res['contact_cost'].items()], _against_newton)


def _against_newton(fig: dict) -> str:
    mine = fig['ours']
    return (f"the project's cheapest at that error or better: {mine['run']} at "
            f"{mine['error']:.2%}, Newton's CPU {fig['ratio']:.2f}x its")


def write_outputs(results: dict, out: Path, progress) -> None:
    peer_outputs(results, out, progress, 'contact', 'A sheet lowered onto a sphere and onto a '
                 "table: the project's runs and Newton's semi-implicit run with contact")

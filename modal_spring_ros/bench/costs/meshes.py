"""
Mesh benchmark: a user's object brought as a mesh file, from the file to its stream.

Two objects of about 10,000 particles, made for the run as mesh files in a temporary folder and
loaded as a user's scene file is: a cloth (0.5 m, 100 x 100 vertices irregularly triangulated,
bending 1e-4 N m, hanging from its top edge: modes about its loaded shape) and a solid (an
ellipsoid 12 x 8 x 8 cm whose closed surface of 5,000 vertices is filled, glued at its base).
Each case runs in its own process (its peak memory is its own) and measures, with the progress
of each stage passed on:

- **load**: reading the mesh, building its springs, masses and bending, and the shape it hangs
  in; **precompute**: the band's rest modes (:data:`MODES`, the node's default), the figure
  the node's start waits for; against the goal of :data:`GOAL_S` seconds on a 2-core machine;
- **step** of the modal run (the band's modes) and of the full run, each at its own stable step
  (0.9 of its explicit limit), and their cost per simulated second: the ratio is the saving;
- **frame**: positions, cloud and serialisation as the node makes them
  (:func:`.steps.frame_costs`).
"""
from __future__ import annotations

from pathlib import Path
import resource
import tempfile
import time
from typing import Callable

from modal_spring_ros.bench.child_run import in_child
from modal_spring_ros.bench.costs.steps import frame_costs, median_step_seconds
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.scenes.schema import scene_from_yaml
import numpy as np
from scipy.spatial import ConvexHull, Delaunay

#: rest modes of the band (the node's default ``modal.max_modes``)
MODES = 32
#: load and precompute within this, s (on the 2-core machine)
GOAL_S = 20.0
#: (label, kind, size): the cloth's vertices per side, the solid's skin vertices
CASES = [('cloth, 10,000 vertices, hanging from its top edge', 'cloth', 100),
         ('solid, 5,000-vertex skin filled to 10,000 particles', 'solid', 5000)]
QUICK_CASES = [('cloth, 900 vertices, hanging from its top edge', 'cloth', 30),
               ('solid, 500-vertex skin filled', 'solid', 500)]


def cloth_mesh(side: int, size: float = 0.5, seed: int = 1, top: float = 1.0,
               jitter: float = 0.25) -> tuple[np.ndarray, np.ndarray]:
    """
    Return a square cloth in the x-z plane, its top edge at z = ``top``, irregularly meshed.

    ``side`` x ``side`` vertices, the inner ones moved at random (seeded) by up to ``jitter`` of
    their spacing, then Delaunay triangles.
    """
    h = size / (side - 1)
    u, v = np.meshgrid(np.arange(side) * h, np.arange(side) * h)
    p = np.column_stack([u.ravel(), v.ravel()])
    inner = np.all((p > 1e-9) & (p < size - 1e-9), axis=1)
    p[inner] += np.random.default_rng(seed).uniform(-jitter, jitter, (int(inner.sum()), 2)) * h
    return np.column_stack([p[:, 0], np.zeros(len(p)), p[:, 1] + top - size]), \
        Delaunay(p).simplices


def ellipsoid_mesh(count: int, half: tuple[float, float, float] = (0.06, 0.04, 0.04)
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Return a closed ellipsoid surface of ``count`` vertices (Fibonacci points, their hull)."""
    k = np.arange(count) + 0.5
    z = 1.0 - 2.0 * k / count
    turn = np.pi * (1.0 + 5.0 ** 0.5) * k
    ring = np.sqrt(1.0 - z ** 2)
    points = np.column_stack([ring * np.cos(turn), ring * np.sin(turn), z]) * half
    points[:, 2] += half[2]                                  # resting on z = 0
    faces = ConvexHull(points).simplices
    corners = points[faces]
    outward = np.einsum('ij,ij->i', np.cross(corners[:, 1] - corners[:, 0],
                                             corners[:, 2] - corners[:, 0]),
                        corners.mean(axis=1) - points.mean(axis=0)) > 0.0
    faces[~outward] = faces[~outward][:, ::-1]
    return points, faces


def scene_text(kind: str, mesh_file: str) -> str:
    """Return the scene file of a case's object (its mesh named relative to it)."""
    if kind == 'cloth':
        body = ('mesh: {file: %s, kind: surface}\n'
                'material: {density: 0.2, stiffness: 400.0, bending: 1.0e-4}\n'
                'fixed: {box: {min: [-1, -1, 0.999], max: [1, 1, 1.001]}}\n'
                'damping: {rayleigh: {alpha: 0.3, beta: 0.002}}\n')
    else:
        body = ('mesh: {file: %s, kind: volume}\n'
                'material: {density: 1000.0, stiffness: 1.0e5}\n'
                'fixed: {box: {min: [-1, -1, -0.001], max: [1, 1, 0.004]}}\n'
                'damping: {rayleigh: {alpha: 2.0}}\n')
    return (f'name: bench_{kind}\ndimension: 3\n' + body % mesh_file
            + 'gravity: [0.0, 0.0, -9.81]\n')


def write_obj(path: Path, vertices: np.ndarray, faces: np.ndarray) -> Path:
    """Write a Wavefront OBJ file of ``vertices`` and triangles ``faces``; return its path."""
    lines = [f'v {x:.9f} {y:.9f} {z:.9f}' for x, y, z in vertices]
    lines += [f'f {a + 1} {b + 1} {c + 1}' for a, b, c in faces]
    path.write_text('\n'.join(lines) + '\n')
    return path


def _measure(kind: str, size: int, folder: str, batches: int,
             progress: Callable[[str], None]) -> dict:
    vertices, faces = cloth_mesh(size) if kind == 'cloth' else ellipsoid_mesh(size)
    write_obj(Path(folder) / f'{kind}.obj', vertices, faces)
    scene_file = Path(folder) / f'{kind}.yaml'
    scene_file.write_text(scene_text(kind, f'{kind}.obj'))
    start = time.perf_counter()
    scene = scene_from_yaml(scene_file.read_text(), str(scene_file), progress=progress)
    loaded = time.perf_counter()
    band = FilterBand('lowpass', 0, MODES - 1, 'index')
    modal = build_simulation(scene, SimulationConfig(method='modal', band=band, basis='rest',
                                                     max_modes=MODES), progress=progress)
    modal = modal.with_dt(0.9 * modal.stability_limit())
    precomputed = time.perf_counter()
    full = build_simulation(scene, SimulationConfig(method='full', max_modes=8))
    full = full.with_dt(0.9 * full.stability_limit())
    result = {'particles': scene.n_particles, 'springs': scene.n_springs,
              'hinges': scene.bending.count if scene.bending is not None else 0,
              'load_s': loaded - start, 'precompute_s': precomputed - loaded}
    for name, sim in (('modal', modal), ('full', full)):
        steps = max(1, int(0.02 / sim.dt)) if name == 'modal' else 20
        step_s = median_step_seconds(sim, batches, steps)
        result[f'{name}_step_us'] = 1e6 * step_s
        result[f'{name}_dt'] = sim.dt
        result[f'{name}_cpu_per_sim_s'] = step_s / sim.dt
    result.update(frame_costs(modal, batches))
    result['peak_mb'] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return result


def run(quick: bool, progress: Callable[[str], None]) -> list[dict]:
    results = []
    cases = QUICK_CASES if quick else CASES
    with tempfile.TemporaryDirectory(prefix='modal_spring_bench_') as folder:
        for k, (label, kind, size) in enumerate(cases):
            progress(f'meshes {k + 1}/{len(cases)}: {label}')
            value = in_child(_measure, kind, size, folder, 3 if quick else 7,
                             what=f'meshes: {label}', progress=lambda m: progress(f'  {m}'))
            value.update(label=label, kind=kind,
                         ready_s=value['load_s'] + value['precompute_s'],
                         saving=value['full_cpu_per_sim_s'] / value['modal_cpu_per_sim_s'])
            results.append(value)
    return results


def table(results: list[dict]) -> str:
    lines = [f"{'case':54s} {'load s':>7s} {'modes s':>8s} {'ready s':>8s} {'modal us':>9s} "
             f"{'full us':>8s} {'x full':>7s} {'us/frame':>9s} {'peak MB':>8s}"]
    for r in results:
        lines.append(f"{r['label']:54s} {r['load_s']:7.1f} {r['precompute_s']:8.1f} "
                     f"{r['ready_s']:8.1f} {r['modal_step_us']:9.1f} {r['full_step_us']:8.1f} "
                     f"{r['saving']:7.0f} {r['frame_total_us']:9.0f} {r['peak_mb']:8.0f}")
    lines.append(f'(ready: load and the {MODES} modes, goal {GOAL_S:g} s; x full: the full '
                 "run's CPU per simulated second over the modal run's, each at 0.9 of its "
                 'explicit limit)')
    return '\n'.join(lines)


def write_outputs(results: list[dict], out, progress) -> None:
    """Write nothing: this suite has only its JSON results."""

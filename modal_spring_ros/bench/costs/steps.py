"""
Step benchmark: time per step and basis cost, as medians, with peak memory.

Each case runs in its own child process (so its peak memory is its own): it builds the
simulation, warms up, then times repeated batches of steps and reports the median time per
step. Ratios against the full physical run are measured in the same invocation. A modal case
also times one frame as the node makes it (each particle's movement from rest, the cloud
written from it in place, its serialisation) against the same frame made with new arrays
(positions in float64, a new cloud and a copy of its bytes), in the same process.
"""
from __future__ import annotations

import array
import concurrent.futures
import resource
import statistics
import time
from typing import Callable

from modal_spring_ros.bags.messages.pointcloud import CloudBuffer, to_pointcloud2
from modal_spring_ros.bench.child_run import in_child
from modal_spring_ros.core.bases.basis import ModalBasis
from modal_spring_ros.core.factory import force_options
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.simulations import FullSimulation, ModalSettings, ModalSimulation
from modal_spring_ros.runs.sample_cache import sample_cache
from modal_spring_ros.scenes.resources import load_scene
from rclpy.serialization import serialize_message
from std_msgs.msg import Header

#: (label, scene, method, kept modes or None, dt, steps between spring evaluations); the
#: method "derivatives" is the modal method with the band's derivative coordinates
CASES = [
    ('sheet_10x10 modal 15 modes', 'sheet_10x10', 'modal', 15, 5e-4, 1),
    ('sheet_10x10 modal 15 modes + derivatives', 'sheet_10x10', 'derivatives', 15, 5e-4, 1),
    ('sheet_10x10 modal 15 modes, springs /10', 'sheet_10x10', 'modal', 15, 5e-4, 10),
    ('sheet_10x10 full', 'sheet_10x10', 'full', None, 5e-4, 1),
    ('sheet_100x100 modal 32 modes', 'sheet_100x100', 'modal', 32, 1e-4, 1),
    ('sheet_100x100 modal 32 modes, springs /10', 'sheet_100x100', 'modal', 32, 1e-4, 10),
    ('sheet_100x100 modal 32 modes + derivatives', 'sheet_100x100', 'derivatives', 32, 1e-4,
     1),
    ('sheet_100x100 full', 'sheet_100x100', 'full', None, 1e-4, 1),
    ('sheet_316x316 modal 32 modes, sampled springs', 'sheet_316x316', 'sampled', 32, 1e-4,
     1),
]
#: cases too slow to set up for --quick (the 100k sheet's modes and spring sample)
SLOW_SCENES = ('sheet_316x316',)


def _measure(scene_name: str, method: str, modes: int | None, dt: float, refresh: int,
             batches: int, batch_steps: int) -> dict:
    model = MassSpringModel(load_scene(scene_name))
    start = time.perf_counter()
    if method in ('modal', 'derivatives', 'sampled'):
        basis = ModalBasis(model, initial_modes=modes, samples=sample_cache())
        forces = force_options('sampled' if method == 'sampled' else 'exact', refresh, 0.01)
        kind = 'derivatives' if method == 'derivatives' else 'rest'
        sim = ModalSimulation(model, basis, FilterBand('lowpass', 0, modes - 1, 'index'),
                              ModalSettings(dt=dt, forces=forces, basis_kind=kind))
        basis_seconds = time.perf_counter() - start
    else:
        basis = ModalBasis(model, initial_modes=8)  # for the damping and stability limit
        basis_seconds = time.perf_counter() - start
        sim = FullSimulation(model, dt=dt, basis=basis)
    step_s = median_step_seconds(sim, batches, batch_steps)
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return {'step_us': 1e6 * step_s, 'basis_s': basis_seconds, 'peak_mb': peak_mb, 'dt': dt,
            **(frame_costs(sim, batches) if method != 'full' else {})}


def median_step_seconds(sim, batches: int, batch_steps: int) -> float:
    """Return the median time of one step over ``batches`` batches, after one for warm-up, s."""
    sim.step(batch_steps)  # warm-up
    times = []
    for _ in range(batches):
        t0 = time.perf_counter()
        sim.step(batch_steps)
        times.append((time.perf_counter() - t0) / batch_steps)
    return statistics.median(times)


def frame_costs(sim, batches: int) -> dict:
    """
    Return the median cost of one frame's parts, us, as the node makes it and with copies.

    Measured in a thread of its own, as the node makes its frames: glibc's allocator gives a
    thread's large buffers (rclpy's copies of the cloud) back to it, where in the main thread it
    maps and unmaps them each time (up to 7 times the serialisation's cost at 500k particles).
    """
    with concurrent.futures.ThreadPoolExecutor(1) as pool:
        return pool.submit(_frame_costs, sim, batches).result()


def _frame_costs(sim, batches: int) -> dict:
    cloud = CloudBuffer(sim.model.scene.rest_positions)
    header = Header(frame_id='world')

    def median_us(work: Callable[[], object]) -> float:
        work()
        times = []
        for _ in range(batches):
            t0 = time.perf_counter()
            for _ in range(10):
                work()
            times.append((time.perf_counter() - t0) / 10)
        return 1e6 * statistics.median(times)
    lean = {'movement': median_us(lambda: sim.movement_into(cloud.movement)),
            'cloud': median_us(cloud.write_movement),
            'serialise': median_us(lambda: serialize_message(cloud.message(header)))}
    rest = sim.model.scene.rest_positions
    copying = median_us(lambda: serialize_message(copied_cloud(sim.positions(), rest, header)))
    return {'frame_us': lean, 'frame_total_us': sum(lean.values()),
            'frame_with_copies_us': copying}


def copied_cloud(positions, rest, header: Header):
    """Return the cloud as a frame made with new arrays makes it: new bytes, copied once more."""
    msg = to_pointcloud2(positions, rest, header)
    msg.data = array.array('B', msg.data)  # what an unchecked message does with its bytes
    return msg


def run(quick: bool, progress: Callable[[str], None]) -> list[dict]:
    results = []
    cases = [c for c in CASES if not (quick and c[1] in SLOW_SCENES)]
    for k, (label, scene, method, modes, dt, refresh) in enumerate(cases):
        progress(f'steps {k + 1}/{len(cases)}: {label}')
        small = scene == 'sheet_10x10'
        batches = 5 if quick else 15
        batch_steps = (400 if small else 20) if quick else (2000 if small else 100)
        res = in_child(_measure, scene, method, modes, dt, refresh, batches, batch_steps,
                       what=f'steps: {label}')
        res.update(label=label, scene=scene, method=method, modes=modes)
        results.append(res)
    by = {r['label']: r for r in results}
    for r in results:
        full = by.get(f"{r['scene']} full")
        r['speedup_vs_full'] = full['step_us'] / r['step_us'] if full else None
        rest = by.get(r['label'].replace(' + derivatives', '')) \
            if r['method'] == 'derivatives' else None
        r['cost_vs_rest_modes'] = r['step_us'] / rest['step_us'] if rest else None
    return results


def table(results: list[dict]) -> str:
    lines = [f"{'case':48s} {'us/step':>10s} {'basis s':>8s} {'peak MB':>8s} {'x full':>7s} "
             f"{'x rest':>7s} {'us/frame':>9s} {'copying':>8s}"]
    for r in results:
        ratio = f"{r['speedup_vs_full']:.1f}" if r['speedup_vs_full'] else '-'
        rest = f"{r['cost_vs_rest_modes']:.2f}" if r.get('cost_vs_rest_modes') else '-'
        frame = f"{r['frame_total_us']:.0f}" if 'frame_total_us' in r else '-'
        copying = f"{r['frame_with_copies_us']:.0f}" if 'frame_with_copies_us' in r else '-'
        lines.append(f"{r['label']:48s} {r['step_us']:10.1f} {r['basis_s']:8.2f} "
                     f"{r['peak_mb']:8.0f} {ratio:>7s} {rest:>7s} {frame:>9s} {copying:>8s}")
    return '\n'.join(lines)


def write_outputs(results: dict, out, progress) -> None:
    """Write nothing: this suite has only its JSON results."""

"""
The automatic choice's promise on demanding scenes: meshes, big turns, long runs, many particles.

The suite ``promise`` checks ``modal.auto`` on small random lattices over 3 s; users bring more.
Each seed of :func:`~modal_spring_ros.scenes.generator.demanding_scene` is a solid or a shell
read from a mesh file, or a sheet of 5,000-7,000 particles, its clamp turning +-90 degrees,
shaking or still, over 20-40 s. Each is planned as ``modal_spring_sim --auto --duration`` plans
it, at 1 % and at 0.3 %, and checked as the suite ``promise`` checks (one converged full run the
truth for both tolerances: :func:`~modal_spring_ros.bench.accuracy.promise.check_scene`): the
error over the whole run and in every 0.25 s window, and what the whole run costs, planning
included, against the full run at its default step and at the longest step that meets ``T``.

Results: ``promise_demanding.json``, ``.csv`` and ``.png``, as the suite ``promise`` draws them.
"""
from __future__ import annotations

from pathlib import Path
import tempfile
from typing import Callable

from modal_spring_ros.bench.accuracy import promise
from modal_spring_ros.scenes.generator import demanding_scene

SEEDS, QUICK_SEEDS = 7, 1
NAME = 'promise_demanding'


def measure(seed: int) -> list[dict]:
    """Plan ``demanding_scene(seed)`` at every tolerance and check each plan (a row each)."""
    with tempfile.TemporaryDirectory(prefix='demanding_') as folder:
        scene = demanding_scene(seed, Path(folder))
    rows = promise.check_scene(scene, seed, promise.TOLERANCES, scene.default_duration)
    for row in rows:
        row['kind'] = scene.description.rsplit(': ', 1)[-1]
    return rows


def run(quick: bool, progress: Callable[[str], None], seeds: list[int] | None = None) -> dict:
    """Check every seed (``QUICK_SEEDS`` with ``quick``), or only ``seeds``."""
    if seeds is None:
        seeds = list(range(QUICK_SEEDS if quick else SEEDS))
    return promise.in_workers(measure, seeds, NAME, progress)


def select_seeds(text: str) -> list[int]:
    """
    Return the seeds ``text`` lists: numbers and ranges, comma-separated (``1-6``, ``0,2,5``).

    :raises ValueError: not such a list, or a seed outside ``0 .. SEEDS - 1``.
    """
    seeds: list[int] = []
    for part in (p.strip() for p in text.split(',')):
        first, dash, last = part.partition('-')
        if not first.strip().isdigit() or (dash and not last.strip().isdigit()):
            raise ValueError(f"'{part}' is not a seed or a range of seeds (such as 1-6)")
        low, high = int(first), int(last) if dash else int(first)
        if low > high or high >= SEEDS:
            raise ValueError(f"'{part}': the seeds are 0 to {SEEDS - 1}, each range ascending")
        seeds += [s for s in range(low, high + 1) if s not in seeds]
    return seeds


def table(results: dict) -> str:
    lines = [promise.table(results), '',
             f"{'seed':>4s} {'kind':>13s} {'particles':>9s} {'run s':>5s} {'T':>5s} "
             f"{'chose':>6s} {'measured':>8s} {'printed':>8s} {'worst 0.25 s':>12s} "
             f"{'whole/default':>13s} {'whole/at T':>10s}"]
    for r in results['rows']:
        if r['refused']:
            lines.append(f"{r['seed']:4d} {r.get('kind', ''):>13s} refused: {r['refused'][:70]}")
            continue
        lines.append(f"{r['seed']:4d} {r.get('kind', ''):>13s} {r['particles']:9d} "
                     f"{r['duration_s']:5.0f} {r['tolerance']:5.1%} {r['method']:>6s} "
                     f"{r['achieved']:8.2%} {r['printed']:8.2%} {r['worst_window']:12.2%} "
                     f"{r['whole_vs_default']:13.2f} {r['whole_vs_at_t']:10.2f}")
    return '\n'.join(lines)


def write_outputs(results: dict, out: Path, progress) -> None:
    promise.write_outputs(results, out, progress, NAME)

"""
Load a run for comparison from wherever it was recorded.

A ``.npz`` run or a bag (folder or ``.mcap``), with the band its recorded settings kept when the
bag says.
"""
from __future__ import annotations

from pathlib import Path

from modal_spring_ros.bags.files.reader import BagReader
from modal_spring_ros.bags.files.sim_time import simulation_times
from modal_spring_ros.bags.files.writer import BagError
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.runs.comparison import load_npz_run, RunData
from modal_spring_ros.runs.run_memory import positions_budget
from modal_spring_ros.runs.sample_cache import sample_cache
from modal_spring_ros.scenes.fields.limits import available_memory


def load_run(path: str | Path, topic: str = '/points') -> RunData:
    """
    Return a ``.npz`` run or a bag (folder or ``.mcap``) as arrays. Raises BagError/RunError.

    A bag's frames are timed by their recorded ``sim_time`` where it has one (a node recording
    stamped with the node's clock), else by their stamps.
    """
    path = Path(path)
    if not path.exists():
        raise BagError(f'{path}: no such run (.npz, bag folder or .mcap)')
    if path.suffix == '.npz':
        return load_npz_run(path)
    bag = BagReader(path)
    stamps, frames = bag.points(topic, simulation_times(bag, topic) or None,  # simulation time
                                max_bytes=positions_budget())
    rec = bag.run_record()
    scene = bag.scene()
    label, band = '', None
    if 'config' in rec and scene is not None:
        config = SimulationConfig.from_dict(rec['config'])
        label = f'{config.method} {config.band.describe()}'
        sim = build_simulation(scene, config, allow_unstable=True, samples=sample_cache(),
                               memory_available=available_memory())
        kept = sim.basis.frequencies_hz[sim.kept_modes]
        if config.method == 'modal':
            band = (float(kept.min()), float(kept.max()))
    return RunData(path.name, stamps, frames, scene, band, label)

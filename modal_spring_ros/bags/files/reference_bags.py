"""
The reference runs of ``sheet_10x10`` in ``bags/``: remade by one command.

    python -m modal_spring_ros.bags.files.reference_bags [FOLDER]      (default: bags)

Five runs of 3 s, a frame every 33 steps (about 60 Hz), written losslessly as rosbag2 MCAP
bags: the full physical run, the modal run with every mode, the paper's fig. 10b low-pass
(modes 0..14), its fig. 10d band-pass (modes 2..48) and a high-pass above 10 Hz. The bags
replace earlier ones of the same names in FOLDER.
"""
from __future__ import annotations

from pathlib import Path
import shutil
import sys

from modal_spring_ros.bags.files.capture import RunBagWriter
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.runs.run import record
from modal_spring_ros.runs.sample_cache import sample_cache
from modal_spring_ros.scenes.resources import load_scene

SCENE = 'sheet_10x10'
DURATION_S = 3.0
FRAME_EVERY = 33
RUNS = {
    'sheet_10x10_full': SimulationConfig(method='full'),
    'sheet_10x10_allpass': SimulationConfig(),
    'sheet_10x10_lowpass_0_14': SimulationConfig(band=FilterBand('lowpass', 0, 14, 'index')),
    'sheet_10x10_bandpass_2_48': SimulationConfig(band=FilterBand('bandpass', 2, 48, 'index')),
    'sheet_10x10_highpass_10hz': SimulationConfig(band=FilterBand('highpass', 10.0)),
}


def write_reference_bags(folder: str | Path) -> list[Path]:
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for name, config in RUNS.items():
        target = folder / name
        if target.exists():
            shutil.rmtree(target)
        sim = build_simulation(load_scene(SCENE), config, samples=sample_cache())
        bag = RunBagWriter(target, sim.model.scene, config, dt=sim.dt,
                           frame_every=FRAME_EVERY, duration=DURATION_S)
        try:
            record(sim, DURATION_S, frame_every=FRAME_EVERY, on_frame=bag.frame)
        finally:
            bag.close()
        written.append(target)
        print(f'wrote {target}')
    return written


if __name__ == '__main__':
    write_reference_bags(sys.argv[1] if len(sys.argv) > 1 else 'bags')

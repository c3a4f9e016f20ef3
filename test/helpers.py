"""What several tests share: where things are, and scenes made for a test."""
from __future__ import annotations

import copy
import os
from pathlib import Path

from modal_spring_ros.scenes.resources import load_scene
from modal_spring_ros.scenes.schema import scene_from_dict

#: the repository (a source checkout)
REPO = Path(__file__).resolve().parents[1]
#: the reference bags shipped with the package
BAGS = REPO / "bags"
#: the real rosbag2 recordings beside the repository (CI has them)
REAL_BAGS = Path(os.environ.get("MODAL_SPRING_REAL_BAGS", REPO.parent / "shared" / "real_bags"))


def variant(name: str, **changes):
    """A built-in scene's full definition with top-level fields replaced, validated."""
    data = copy.deepcopy(load_scene(name).to_dict())
    data.update(changes)
    return scene_from_dict(data, source=f"{name} variant")


def oscillator(k: float = 400.0, m: float = 0.25, gravity: float = 0.0):
    """One free mass on one spring (1D): omega = sqrt(k / m)."""
    return scene_from_dict({
        "name": "oscillator", "dimension": 1, "axis": "x",
        "particles": {"positions": [[0.0, 0.0], [1.0, 0.0]], "mass": [1.0, m]},
        "springs": {"pairs": [[0, 1]], "stiffness": k},
        "fixed": {"indices": [0]}, "gravity": [gravity, 0.0, 0.0],
    })

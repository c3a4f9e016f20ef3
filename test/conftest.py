"""Shared fixtures: scenes built from the built-in ones with a few fields changed."""
from __future__ import annotations

import copy

import pytest

from modal_spring_ros.core.basis import ModalBasis
from modal_spring_ros.core.model import MassSpringModel
from modal_spring_ros.scenes.resources import load_scene
from modal_spring_ros.scenes.schema import scene_from_dict


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


@pytest.fixture(scope="session")
def sheet_undamped_still():
    """sheet_10x10 without damping and without anchor motion (a conservative system)."""
    scene = variant("sheet_10x10", damping={"ratio": 0.0}, anchor_motion=[])
    model = MassSpringModel(scene)
    return model, ModalBasis(model)


@pytest.fixture(scope="session")
def sheet_10x10():
    model = MassSpringModel(load_scene("sheet_10x10"))
    return model, ModalBasis(model)

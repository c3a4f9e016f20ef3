"""Fixtures shared by the suite (helpers they use live in ``helpers.py``)."""
from __future__ import annotations

import os
import tempfile

from helpers import variant
from modal_spring_ros.core.basis import ModalBasis
from modal_spring_ros.core.model import MassSpringModel
from modal_spring_ros.scenes.resources import load_scene
import pytest

# Spring samples are cached per run of the suite, never in the user's cache folder (the
# node's processes inherit it).
os.environ['MODAL_SPRING_ROS_CACHE'] = tempfile.mkdtemp(prefix='modal_spring_samples_')


@pytest.fixture(scope='session')
def sheet_undamped_still():
    """sheet_10x10 without damping and without anchor motion (a conservative system)."""
    scene = variant('sheet_10x10', damping={'ratio': 0.0}, anchor_motion=[])
    model = MassSpringModel(scene)
    return model, ModalBasis(model)


@pytest.fixture(scope='session')
def sheet_10x10():
    model = MassSpringModel(load_scene('sheet_10x10'))
    return model, ModalBasis(model)

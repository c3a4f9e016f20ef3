"""Which runs start streaming before their spring sample is trained (ros/start_up.py)."""
from __future__ import annotations

import dataclasses

from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.ros.start_up import first_values, STAGED_SPRINGS
from modal_spring_ros.scenes.resources import load_scene
import pytest

SAMPLED = SimulationConfig(forces='sampled')


@pytest.fixture(scope='module')
def large():
    scene = load_scene('sheet_100x100')
    assert scene.n_springs >= STAGED_SPRINGS
    return scene


def test_a_large_scene_asked_for_sampled_springs_starts_with_refreshed_ones(large):
    assert first_values(SAMPLED, large) == {'modal.forces': 'refreshed'}


@pytest.mark.parametrize('config', [
    SimulationConfig(forces='exact'), SimulationConfig(forces='refreshed'),
    dataclasses.replace(SAMPLED, auto=True),          # the plan measures its own forces
    dataclasses.replace(SAMPLED, method='full')])
def test_other_runs_start_as_asked(large, config):
    assert first_values(config, large) == {}


def test_a_scene_below_the_size_starts_as_asked():
    scene = load_scene('sheet_32x32')
    assert scene.n_springs < STAGED_SPRINGS
    assert first_values(SAMPLED, scene) == {}

"""The built-in scenes' benchmark: the plan as predicted against the plan measured, one run."""
from __future__ import annotations

from modal_spring_ros.bench.accuracy import auto_scenes
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import predicted_simulation
from modal_spring_ros.scenes.resources import load_scene
import pytest


def test_the_predicted_plan_is_the_one_auto_started_from():
    scene = load_scene('sheet_10x10')
    config = SimulationConfig(auto=True, tolerance=0.01)
    predicted = predicted_simulation(scene, config)
    assert predicted.method == 'modal' and predicted.pilot is None
    assert predicted.watch_reference is None                # nothing measured, nothing watched
    assert predicted.mode_choice is not None and predicted.coordinates == 16
    with pytest.raises(ValueError, match='needs auto'):
        predicted_simulation(scene, SimulationConfig())


@pytest.mark.slow
def test_a_built_in_scene_is_checked_both_ways_in_one_run(tmp_path):
    row = auto_scenes.measure('chain_2', 0.01)
    assert 'refused' not in row and row['duration_s'] == 5.0
    # auto keeps its promise over the scene's run, against the converged full run
    assert 0.0 < row['auto_error'] <= 0.01 and 0.0 < row['printed'] <= 0.01
    assert row['predicted_error'] > 0.0 and row['predicted_cost'] > 0.0
    assert row['auto_cost'] > 0.0 and row['auto_method'] in ('modal', 'full')
    text = auto_scenes.table({'rows': [row]})
    assert text.splitlines()[1].startswith('chain_2') and '1.0%' in text
    auto_scenes.write_outputs({'rows': [row]}, tmp_path, lambda msg: None)
    assert len((tmp_path / 'auto.csv').read_text().splitlines()) == 2

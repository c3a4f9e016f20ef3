"""
What the node reports on /diagnostics about its run.

The large-deformation warning and the automatic mode choice, over real DDS.
"""
from __future__ import annotations

import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest
from ros_harness import (assert_resimulates_exactly, Client, frames_since, node_of,
                         node_with_client, running_node, SimTimes, stderr_excerpt,
                         streaming_statuses, wait_for)
from sensor_msgs.msg import PointCloud2

pytestmark = pytest.mark.ros


def test_the_node_flags_the_large_deformation_and_keeps_streaming():
    """
    With rest modes (the paper's basis) the node warns once the deformation leaves their regime.

    And keeps streaming.
    """
    with node_with_client('scene:=sheet_10x10_resonance', 'filter.type:=lowpass',
                          'filter.by:=index', 'filter.high_mode:=14', 'realtime_factor:=2.0',
                          'modal.basis:=rest', namespace='fold') as (node, client):
        points = client.collect(PointCloud2, '/fold/points', qos=500)
        diags = client.collect(DiagnosticArray, '/diagnostics')

        def warned():
            return any(node_of(d.status[0]).startswith('/fold/') and
                       d.status[0].level == DiagnosticStatus.WARN and
                       'large deformation' in d.status[0].message for _, d in diags)
        assert wait_for(warned, 30)
        window = frames_since(points, time.monotonic(), 30)          # not frozen
        for m in window:
            assert np.isfinite(np.frombuffer(bytes(m.data), dtype='<f4')).all()


def test_node_automatic_mode_choice_is_reported_as_the_simulator_chooses_it():
    with node_with_client('modal.auto:=true', 'modal.tolerance:=0.05',
                          namespace='auto') as (node, client):
        diags = client.collect(DiagnosticArray, '/diagnostics')

        def planned():
            return [values for values in map(_values_of, streaming_statuses(diags, '/auto/'))
                    if values.get('automatic mode choice', 'off') != 'off']
        assert wait_for(planned, 60), stderr_excerpt(node.stderr())
        values = planned()[-1]
        assert values['automatic mode choice'].startswith('5 modes up to 20.44 Hz')
        assert values['modes stepped'] == '5'
        # the spring-force refresh follows the choice: what the engine chooses headless
        expected = build_simulation(load_scene('sheet_10x10'),
                                    SimulationConfig(auto=True, tolerance=0.05))
        assert values['force refresh (steps)'] == str(expected.force_refresh)
        # the error measured over the scene's run, as modal_spring_sim prints it
        assert values['automatic choice measured'] == expected.pilot.describe()
        assert ' over a 5 s run (measured ' in values['automatic choice measured']
        assert expected.force_refresh > 1
        assert wait_for(lambda: float(_values(diags, '/auto/')['measured force error']) > 0, 10)
        assert float(_values(diags, '/auto/')['measured force error']) < 0.01


def test_an_automatic_plan_streams_the_full_run_until_it_is_measured(tmp_path):
    """sheet_32x32 at 1 %: seconds of planning, streamed by the full run meanwhile."""
    capture = tmp_path / 'capture'
    client = Client('planned_client')       # subscribed before the node: its first reports
    points = client.collect(PointCloud2, '/planned/points', qos=1000)
    sim_time = SimTimes().subscribe(client, '/planned/sim_time')
    diags = client.collect(DiagnosticArray, '/diagnostics')
    with client, running_node('scene:=sheet_32x32', 'modal.auto:=true', 'modal.tolerance:=0.01',
                              f'record.bag:={capture}', namespace='planned') as node:
        def planned():
            return [values for values in map(_values_of, streaming_statuses(diags, '/planned/'))
                    if values.get('automatic mode choice', 'off') != 'off']
        assert wait_for(planned, 120), stderr_excerpt(node.stderr())
        # the first frames came from the full run while the plan was measured, and said so
        first = _values_of(streaming_statuses(diags, '/planned/')[0])
        assert first['method'] == 'full', first
        assert first['parameter changes pending'] == "method='modal', modal.auto=True"
        log = node.stderr()
        assert "streaming while method='modal', modal.auto=True is prepared" in log
        assert 'planning: measuring modes up to' in log          # the pilot's progress
        assert "the run takes method='modal', modal.auto=True" in log
        # then the plan, as modal_spring_sim chooses it headless
        values = planned()[-1]
        assert values['method'] == 'modal' and values['parameter changes pending'] == 'none'
        expected = build_simulation(load_scene('sheet_32x32'),
                                    SimulationConfig(auto=True, tolerance=0.01))
        assert values['automatic choice measured'] == expected.pilot.describe()
        # the parameters read what was asked throughout
        assert client.get_parameters('planned/modal_spring', 'method', 'modal.auto') == [
            'modal', True]
        # the plan took the full run's state: no frame jumps (the sheet, released from rest,
        # swings below 0.25 m/s; a state lost at the switch moves it by its sag, centimetres,
        # in one frame: over 0.6 m/s at 60 Hz)
        assert sim_time.fastest(points) < 0.4
    # the capture holds the full run, then the change to the plan: it re-simulates exactly
    assert assert_resimulates_exactly(capture, tmp_path / 'again', changes=1) > 30


def _values_of(status) -> dict[str, str]:
    return {kv.key: kv.value for kv in status.values}


def _values(diags, prefix):
    return _values_of(streaming_statuses(diags, prefix)[-1])


def test_the_node_streams_with_sampled_springs():
    """
    modal.forces sampled on sheet_32x32.

    The sample is trained at start (cached for the suite) and reported on /diagnostics.
    """
    with node_with_client('scene:=sheet_32x32', 'modal.forces:=sampled', 'filter.type:=lowpass',
                          'filter.high_hz:=30.0', namespace='sampled') as (node, client):
        points = client.collect(PointCloud2, '/sampled/points')
        diags = client.collect(DiagnosticArray, '/diagnostics')
        assert wait_for(lambda: len(points) > 10, 60)
        assert wait_for(lambda: streaming_statuses(diags, '/sampled/'), 10)
        assert _values(diags, '/sampled/')['spring forces'].startswith('sampled: ')
        for _, m in points:
            assert np.isfinite(np.frombuffer(bytes(m.data), dtype='<f4')).all()


def test_a_large_scene_streams_while_its_spring_sample_is_trained(monkeypatch, tmp_path):
    """
    sheet_100x100 (39,402 springs) with modal.forces sampled and nothing in the sample cache.

    The first frames come with refreshed springs (every spring every few steps) while the
    sample is trained in the worker process, then the run takes the sample (its log says when),
    its stream unbroken; the parameter reads sampled throughout.
    """
    monkeypatch.setenv('MODAL_SPRING_ROS_CACHE', str(tmp_path))      # trained, not loaded
    with node_with_client('scene:=sheet_100x100', 'modal.forces:=sampled', 'modal.basis:=rest',
                          'filter.type:=lowpass', 'filter.by:=index', 'filter.high_mode:=15',
                          namespace='staged') as (node, client):
        points = client.collect(PointCloud2, '/staged/points', qos=500)
        diags = client.collect(DiagnosticArray, '/diagnostics')

        def reports():
            return [{kv.key: kv.value for kv in s.values}
                    for s in streaming_statuses(diags, '/staged/')]

        assert wait_for(lambda: reports() and reports()[-1]['spring forces'].startswith(
            'sampled: '), 180), reports()[-1:]
        log = node.stderr()
        took = log.find("the run takes modal.forces='sampled'")
        assert 0 < log.find('streaming sheet_100x100') < took, log   # the stream did not wait
        assert 0 <= log.find("streaming while modal.forces='sampled' is prepared") < took
        assert _values(diags, '/staged/')['parameter changes pending'] == 'none'
        assert client.get_parameters('staged/modal_spring', 'modal.forces') == ['sampled']
        assert any(p.name.endswith('.npz') for p in tmp_path.rglob('*'))   # trained, kept
        after = time.monotonic()
        window = frames_since(points, after, 20)                          # streams on
        for m in window:
            assert np.isfinite(np.frombuffer(bytes(m.data), dtype='<f4')).all()

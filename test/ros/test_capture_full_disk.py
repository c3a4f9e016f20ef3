"""
The node's capture (``record.bag``) on a full disk: it stops, says so once, the stream goes on.

The node's outputs with a real rclpy node (no other process), the disk filling at a chosen byte.
"""
from __future__ import annotations

from helpers import fill_disk_after
from modal_spring_ros.bags.files.capture import RunBagWriter
from modal_spring_ros.bags.files.reader import BagReader
from modal_spring_ros.bags.messages.pointcloud import CloudBuffer
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.ros.parameters import PARAMETERS
from modal_spring_ros.ros.stream.diagnostics import StreamReport
from modal_spring_ros.ros.stream.outputs import NodeOutputs
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest
import rclpy
from rclpy.context import Context
from ros_harness import DOMAIN_ID

pytestmark = pytest.mark.ros


def test_a_full_disk_stops_the_capture_once_and_the_stream_goes_on(tmp_path, monkeypatch):
    fill_disk_after(monkeypatch, 2_500_000)          # two 1 MiB chunks of 1.7 kB frames
    context = Context()
    rclpy.init(context=context, domain_id=DOMAIN_ID)
    node = rclpy.create_node('capture_probe', context=context)
    try:
        sim = build_simulation(load_scene('sheet_10x10'), SimulationConfig())
        values = {name: default for name, (default, _) in PARAMETERS.items()}
        bag = RunBagWriter(tmp_path / 'run', sim.model.scene, None, dt=sim.dt, frame_every=0,
                           duration=0.0, frame_id='world', source='modal_spring_node',
                           parameters=values, node='/capture_probe')
        outputs = NodeOutputs(node, sim.model.scene, lambda: values, bag)
        errors, published = [], []
        monkeypatch.setattr(node.get_logger(), 'error', errors.append)
        monkeypatch.setattr(outputs._points, 'publish', published.append)
        monkeypatch.setattr(outputs._diagnostics, 'publish', published.append)
        cloud = CloudBuffer(sim.model.scene.rest_positions)
        for _ in range(3000):                         # far more than the disk holds
            sim.step(10)
            cloud.write_run(sim)
            outputs.frame(sim, cloud, False)          # never raises
        assert outputs.recording_stopped.startswith('recording stopped: ')
        assert 'No space left on device' in outputs.recording_stopped
        assert len(errors) == 1 and 'the stream goes on' in errors[0]
        frames = [m for m in published if hasattr(m, 'fields')]
        assert len(frames) == 3000                    # every frame still went out
        outputs.diagnostics(sim.status(), StreamReport(window_s=1.0, frames_in_window=60))
        (status,) = published[-1].status
        assert status.level == status.WARN and 'recording stopped' in status.message
        outputs.close()                               # nothing more to do, nothing raised
        recorded = BagReader(tmp_path / 'run')
        got = list(recorded.messages(['/points']))
        assert 500 < len(got) < 3000                  # what was written stays readable
        first = recorded.decode(got[0])
        assert np.isfinite(np.frombuffer(bytes(first.data), dtype='<f4')).all()
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)

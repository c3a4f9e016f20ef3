"""The node's life cycle over real DDS: clean ends on signals, and a band-change stress test.

Each test starts its own node in its own namespace (so only its own stream is seen)."""
from __future__ import annotations

import signal
import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from sensor_msgs.msg import PointCloud2

from ros_harness import Client, NodeProcess, wait_for

NODE = "modal_spring"
RATE = 60.0


def test_sigint_and_sigterm_end_the_node_cleanly():
    for sig in (signal.SIGINT, signal.SIGTERM):
        node = NodeProcess(namespace="lifecycle")
        client = Client("sig_client")
        points = client.collect(PointCloud2, "/lifecycle/points")
        assert wait_for(lambda: len(points) > 3, 30)
        client.close()
        node.proc.send_signal(sig)
        out, err = node.proc.communicate(timeout=15)
        assert node.proc.returncode == 0, err[-3000:]
        assert "Traceback" not in err


def test_stress_band_changes_every_50ms_keep_the_stream_whole():
    node = NodeProcess(namespace="stress")
    client = Client("stress_client")
    points = client.collect(PointCloud2, "/stress/points", qos=500)
    diagnostics = client.collect(DiagnosticArray, "/diagnostics")
    try:
        assert wait_for(lambda: len(points) > 3, 30)
        bands = [("lowpass", 0.0, 12.0), ("highpass", 10.0, 11.0), ("bandpass", 5.0, 40.0),
                 ("bandstop", 8.0, 30.0), ("allpass", 0.0, 1.0)]
        start = time.monotonic()
        k = 0
        while time.monotonic() - start < 10.0:
            kind, low, high = bands[k % len(bands)]
            (result,) = client.set_parameters(f"stress/{NODE}", atomically=True, filter__type=kind,
                                              filter__low_hz=low, filter__high_hz=high)
            assert result.successful, result.reason
            k += 1
            time.sleep(0.05)
        assert k > 100
        assert node.proc.poll() is None                       # still running
        window = [(t, m) for t, m in points if t >= start]
        times = np.array([t for t, _ in window])
        assert np.diff(times).max() < 5.0 / RATE            # no gap over a few periods
        for _, m in window:
            assert np.isfinite(np.frombuffer(bytes(m.data), dtype="<f4")).all()
        levels = [d.status[0].level for t, d in diagnostics
                  if t >= start and d.status[0].name.startswith("/stress/")]
        assert levels
        assert DiagnosticStatus.ERROR not in levels
    finally:
        client.close()
        code, _, err = node.interrupt()
        assert code == 0 and "Traceback" not in err


def test_params_file_is_accepted_as_ros2_run_would_pass_it():
    from pathlib import Path
    from diagnostic_msgs.msg import DiagnosticArray as Diag
    params = Path(__file__).resolve().parent.parent / "config" / "modal_spring.yaml"
    import os
    import subprocess
    from ros_harness import console_script
    proc = subprocess.Popen([console_script("modal_spring_node"), "--ros-args",
                             "--params-file", str(params), "-r", "__ns:=/params"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=dict(os.environ))
    client = Client("params_client")
    diags = client.collect(Diag, "/diagnostics")
    try:
        assert wait_for(lambda: any(d.status[0].name.startswith("/params/")
                                    for _, d in diags), 30)
        status = next(d.status[0] for _, d in diags if d.status[0].name.startswith("/params/"))
        values = {kv.key: kv.value for kv in status.values}
        assert values["band"] == "lowpass <= 45 Hz" and values["method"] == "modal"
    finally:
        client.close()
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=15)
    assert proc.returncode == 0

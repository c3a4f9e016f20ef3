"""
Streaming benchmark.

Publish rate and end-to-end latency of the node, seen by a subscriber in another process.

The node runs as a user runs it (console script, own process) with ``stamp:=wall``; this
process subscribes to its points and diagnostics and measures the receive rate and the
latency (receipt time minus header stamp, both on this machine's clock), and its start-up: the
wall time from the command to the first cloud, and the CPU time the node's processes (its
worker processes included) had used by then.
"""
from __future__ import annotations

import os
import random
import signal
import statistics
import subprocess
import time
from typing import Callable

from diagnostic_msgs.msg import DiagnosticArray
from modal_spring_ros.bench.costs.busy_load import BusyLoad
from modal_spring_ros.bench.costs.process_cpu import tree_cpu_seconds
from modal_spring_ros.scenes.resources import executable
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from sensor_msgs.msg import PointCloud2

#: a case's environment for the node (``--env=NAME=VALUE``): Fast DDS's own transports, which
#: send clouds over 0.5 MB over UDP (the node otherwise takes the large-segment profile for them,
#: ros/process/shared_memory.py)
FAST_DDS_DEFAULTS = '--env=FASTDDS_BUILTIN_TRANSPORTS=DEFAULT'
#: a case's load beside the node (``--busy=N``): N processes each spinning on a core
#: (:mod:`~modal_spring_ros.bench.costs.busy_load`) from before the node starts until it is stopped
BUSY = '--busy='
#: the paper's method on the lowest 32 rest modes (the node's default adds their derivatives)
_REST_32 = ['filter.type:=lowpass', 'filter.by:=index', 'filter.high_mode:=31',
            'modal.basis:=rest']

#: the 10k sheet beside two busy processes, and the same case on a quiet machine
BUSY_CASE = 'sheet_100x100, modal 32 modes, two busy processes beside it'
QUIET_CASE = 'sheet_100x100, modal 32 modes'
#: the start-up's baseline: the node waits for every mode of the band before its first frame
WAITING = 'sheet_316x316 (100k), modal 32 modes, the first frame waiting for all (baseline)'
#: the case it is the baseline of (the node streams on the lowest modes while the rest come)
EARLY = 'sheet_316x316 (100k), modal 32 modes'

#: the highest DDS domain id ROS 2 accepts
MAX_DOMAIN_ID = 232
#: (label, scene, extra node parameters)
CASES = [
    ('sheet_10x10, modal all modes', 'sheet_10x10', []),
    ('sheet_100x100, modal 32 modes', 'sheet_100x100', _REST_32),
    (BUSY_CASE, 'sheet_100x100', _REST_32 + [f'{BUSY}2']),
    ('sheet_100x100, modal 32 modes + derivatives, sampled springs', 'sheet_100x100',
     ['filter.type:=lowpass', 'filter.by:=index', 'filter.high_mode:=31',
      'modal.forces:=sampled']),
    ('sheet_316x316 (100k), modal 32 modes', 'sheet_316x316', _REST_32),
    (WAITING, 'sheet_316x316', _REST_32 + ['stream_early:=false']),
    ('sheet_316x316 (100k), modal 32 modes, springs every 10 steps', 'sheet_316x316',
     _REST_32 + ['modal.force_refresh:=10']),
    ('sheet_316x316 (100k), modal 32 modes, sampled springs', 'sheet_316x316',
     _REST_32 + ['modal.forces:=sampled']),
    ('sheet_316x316 (100k), sampled springs, Fast DDS default transports (UDP)',
     'sheet_316x316', _REST_32 + ['modal.forces:=sampled', FAST_DDS_DEFAULTS]),
]


def domain_id() -> int:
    """Return the DDS domain to measure on: ``ROS_DOMAIN_ID`` when set, else a random one."""
    given = os.environ.get('ROS_DOMAIN_ID', '').strip()
    if given:
        if not (given.isdigit() and 0 <= int(given) <= MAX_DOMAIN_ID):
            raise ValueError(f'ROS_DOMAIN_ID ({given!r}) must be a whole number from 0 to '
                             f'{MAX_DOMAIN_ID}')
        return int(given)
    return random.randint(110, 200)     # apart from other runs on this machine


def end_node(node: subprocess.Popen) -> None:
    """End a node started here as Ctrl-C does; kill its process group if it outlives 20 s."""
    if node.poll() is None:
        node.send_signal(signal.SIGINT)
        try:
            node.wait(timeout=20)
        except subprocess.TimeoutExpired:
            os.killpg(node.pid, signal.SIGKILL)


def select_cases(case: str | None, quick: bool) -> list[tuple[str, str, list[str]]]:
    """Return the cases to run: those whose label contains ``case``, else all (two quick)."""
    if case is None:
        return CASES[:2] if quick else CASES
    chosen = [c for c in CASES if case.lower() in c[0].lower()]
    if not chosen:
        raise ValueError(f"--case '{case}' matches no stream case (cases: "
                         f"{'; '.join(label for label, _, _ in CASES)})")
    return chosen


def measure(scene: str, params: list[str], seconds: float, startup_timeout: float,
            progress: Callable[[str], None]) -> dict:
    """
    Start the node on ``scene`` with ``params`` and measure its stream (see the module).

    ``params`` are node parameters, and the case's own ``--env=NAME=VALUE`` (the node's
    environment) and ``--busy=N`` (N busy processes beside it throughout).
    """
    domain = domain_id()
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    exe = executable('modal_spring_node')
    args = [str(exe), '--ros-args', '-p', f'scene:={scene}', '-p', 'stamp:=wall']
    busy = 0
    for p in params:
        if p.startswith('--env='):
            name, value = p[len('--env='):].split('=', 1)
            env[name] = value
        elif p.startswith(BUSY):
            busy = int(p[len(BUSY):])
        else:
            args += ['-p', p]
    with BusyLoad(busy):
        return _measure(args, env, domain, scene, seconds, startup_timeout, progress)


def _measure(args: list[str], env: dict, domain: int, scene: str, seconds: float,
             startup_timeout: float, progress: Callable[[str], None]) -> dict:
    started = time.monotonic()
    node = subprocess.Popen(args, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    ctx = Context()
    rclpy.init(context=ctx, domain_id=domain)
    sub = rclpy.create_node('modal_spring_bench_subscriber', context=ctx)
    received: list[tuple[float, float, int]] = []
    diags: list = []
    sub.create_subscription(PointCloud2, '/points', lambda m: received.append(
        (time.time(), m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec, m.width)), 50)
    sub.create_subscription(DiagnosticArray, '/diagnostics', lambda m: diags.append(m), 10)
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(sub)
    try:
        end = time.monotonic() + startup_timeout
        while not received and time.monotonic() < end and node.poll() is None:
            ex.spin_once(timeout_sec=0.1)
        if not received:
            raise RuntimeError(f'no points from the node within {startup_timeout:.0f} s')
        # start-up: from the command to the first cloud, and the CPU the node's processes took
        first_frame_s = time.monotonic() - started
        first_frame_cpu_s = tree_cpu_seconds(node.pid)
        progress(f'{scene}: streaming, measuring {seconds:g} s')
        warm = time.monotonic() + 2.0
        while time.monotonic() < warm:
            ex.spin_once(timeout_sec=0.05)
        received.clear()
        diags.clear()
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            ex.spin_once(timeout_sec=0.05)
    finally:
        ex.shutdown()
        sub.destroy_node()
        rclpy.try_shutdown(context=ctx)
        end_node(node)
    latencies = [1e3 * (r - s) for r, s, _ in received]
    values = {}
    if diags:
        values = {kv.key: kv.value for kv in diags[-1].status[0].values}
    return {
        'scene': scene, 'particles': received[0][2] if received else 0,
        'rate_hz': (len(received) - 1) / (received[-1][0] - received[0][0])
        if len(received) > 1 else 0.0,
        'latency_median_ms': statistics.median(latencies) if latencies else None,
        'latency_p95_ms': sorted(latencies)[int(0.95 * (len(latencies) - 1))]
        if latencies else None,
        'achieved_rtf': float(values.get('achieved real-time factor', 'nan')),
        'step_us': float(values.get('step time (us)', 'nan')),
        'modes': values.get('modes stepped'),
        'first_frame_s': first_frame_s,
        'first_frame_cpu_s': first_frame_cpu_s if first_frame_cpu_s is not None else float('nan'),
    }


def run(quick: bool, progress: Callable[[str], None], case: str | None = None) -> list[dict]:
    """Measure the cases (``case``: only those whose label contains it)."""
    results = []
    cases = select_cases(case, quick)
    for k, (label, scene, params) in enumerate(cases):
        progress(f'stream {k + 1}/{len(cases)}: {label}')
        res = measure(scene, params, 3.0 if quick else 10.0, 240.0, progress)
        res['label'] = label
        results.append(res)
    return results


def table(results: list[dict]) -> str:
    w = max([len('case')] + [len(r['label']) for r in results])
    lines = [f"{'case':{w}s} {'points':>7s} {'rate Hz':>8s} {'lat med ms':>10s} "
             f"{'lat p95 ms':>10s} {'RTF':>6s} {'us/step':>9s} {'1st frame s':>11s} "
             f"{'its CPU s':>9s}"]
    for r in results:
        lines.append(f"{r['label']:{w}s} {r['particles']:7d} {r['rate_hz']:8.1f} "
                     f"{r['latency_median_ms']:10.2f} {r['latency_p95_ms']:10.2f} "
                     f"{r['achieved_rtf']:6.2f} {r['step_us']:9.0f} "
                     f"{r['first_frame_s']:11.1f} {r['first_frame_cpu_s']:9.1f}")
    by_label = {r['label']: r for r in results}
    if QUIET_CASE in by_label and BUSY_CASE in by_label:
        quiet, busy = by_label[QUIET_CASE], by_label[BUSY_CASE]
        latency = busy['latency_median_ms'] / quiet['latency_median_ms']
        lines.append('beside two busy processes the 10k sheet streams at '
                     f"{busy['rate_hz'] / quiet['rate_hz']:.2f}x the quiet rate, real-time "
                     f"factor {busy['achieved_rtf']:.2f} (quiet {quiet['achieved_rtf']:.2f}), "
                     f'median latency {latency:.1f}x')
    if EARLY in by_label and WAITING in by_label:
        early, waiting = by_label[EARLY], by_label[WAITING]
        lines.append('start-up of the 100k sheet: the first frame after '
                     f"{early['first_frame_cpu_s']:.1f} s of CPU streaming early, "
                     f"{waiting['first_frame_cpu_s']:.1f} s waiting for every mode: "
                     f"{waiting['first_frame_cpu_s'] / early['first_frame_cpu_s']:.2f}x less "
                     f"({waiting['first_frame_s'] / early['first_frame_s']:.2f}x in wall time)")
    return '\n'.join(lines)


def write_outputs(results: dict, out, progress) -> None:
    """Write nothing: this suite has only its JSON results."""

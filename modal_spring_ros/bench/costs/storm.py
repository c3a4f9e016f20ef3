"""
Parameter storm benchmark: four clients change the node's settings without pause.

The node runs as a user runs it (console script, own process, ``sheet_32x32``); four clients,
each its own ROS context in its own thread, send ``SetParameters`` requests one after another
for the whole storm (10 minutes; 1 with ``--quick``): band changes of every kind, gains,
damping ranges, publish rates, and requests the node must refuse (an impossible band, a value
out of range). Every answer's time (request sent to response received) is kept, as is the node's
resident memory every few seconds. Reported: requests, those never answered, the answer time's
median, 99th percentile and worst, the share over 1 s, the memory after the first minute and at
the end with its growth per minute fitted over the rest, and whether the stream is still alive.
A PNG chart shows the answer times and the memory over the storm.
"""
from __future__ import annotations

import os
import random
import subprocess
import tempfile
import threading
import time
from typing import Callable

from modal_spring_ros.bench.charts import subplots
from modal_spring_ros.bench.costs.stream import domain_id, end_node
from modal_spring_ros.scenes.resources import executable
import numpy as np
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from sensor_msgs.msg import PointCloud2

SCENE = 'sheet_32x32'
NODE = 'storm/modal_spring'
CLIENTS = 4
#: the storm's length, s (the quick run's)
DURATION_S, QUICK_DURATION_S = 600.0, 60.0
#: a request unanswered for this long is counted lost, s
ANSWER_TIMEOUT_S = 30.0
#: how often the node's memory is read, s
MEMORY_PERIOD_S = 5.0
#: memory is taken as settled after this, s (the first bands' modes and caches are built)
SETTLED_S = 60.0
#: what an answer should take at most: the share above it is reported
SLOW_ANSWER_S = 1.0

_BANDS = ['lowpass', 'highpass', 'bandpass', 'bandstop', 'allpass']


def _double(name: str, value: float) -> Parameter:
    return Parameter(name=name, value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE,
                                                     double_value=float(value)))


def _text(name: str, value: str) -> Parameter:
    return Parameter(name=name, value=ParameterValue(type=ParameterType.PARAMETER_STRING,
                                                     string_value=value))


def random_request(rng: random.Random) -> list[Parameter]:
    """Return one request's parameters: mostly valid changes, some the node must refuse."""
    kind = rng.random()
    low = rng.uniform(0.0, 20.0)
    high = low + rng.uniform(0.5, 30.0)
    if kind < 0.45:                                  # a band, set at once
        return [_text('filter.by', 'hz'), _text('filter.type', rng.choice(_BANDS)),
                _double('filter.low_hz', low), _double('filter.high_hz', high)]
    if kind < 0.55:                                  # gains (dB over a range)
        return [_text('filter.gains', f'{low:.2f}:{high:.2f}:{rng.uniform(-12, 12):.1f}')]
    if kind < 0.65:                                  # a damping range
        return [_text('filter.damping', f'{low:.2f}:{high:.2f}:{rng.uniform(0.01, 0.5):.3f}')]
    if kind < 0.75:
        return [_double('publish_rate_hz', rng.choice([30.0, 60.0, 120.0]))]
    if kind < 0.9:                                   # refused: an impossible band
        return [_text('filter.by', 'hz'), _text('filter.type', 'bandpass'),
                _double('filter.low_hz', 20.0), _double('filter.high_hz', 5.0)]
    return [_double('publish_rate_hz', -1.0)]        # refused: out of range


def _node_rss_mb(pid: int) -> float | None:
    try:
        with open(f'/proc/{pid}/status') as fh:
            for line in fh:
                if line.startswith('VmRSS:'):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        return None
    return None


class _Client(threading.Thread):
    """
    One client: its own context, node and spinning executor; one request at a time.

    It waits for each answer with ``Client.call`` while its executor spins in a thread of its
    own. (Waiting with ``spin_until_future_complete`` instead, rclpy Jazzy leaves work behind
    at every call, ros2/rclpy#1374: its answers took 10 ms at first and 1 s after 10 minutes,
    and a client made anew was fast again.)
    """

    def __init__(self, index: int, domain: int, end: float):
        super().__init__(name=f'storm-client-{index}', daemon=True)
        self.answers: list[tuple[float, float, bool]] = []   # (sent, seconds, accepted)
        self.lost: list[tuple[float, str]] = []   # (sent, what) of requests never answered
        self._rng = random.Random(index)
        self._domain, self._end, self._index = domain, end, index

    def run(self) -> None:
        ctx = Context()
        rclpy.init(context=ctx, domain_id=self._domain)
        node = rclpy.create_node(f'storm_client_{self._index}', context=ctx)
        client = node.create_client(SetParameters, f'/{NODE}/set_parameters')
        executor = SingleThreadedExecutor(context=ctx)
        executor.add_node(node)
        spinner = threading.Thread(target=executor.spin, daemon=True)
        spinner.start()
        try:
            self._matched(client)
            while time.monotonic() < self._end:
                sent = time.monotonic()
                request = random_request(self._rng)
                answer = client.call(SetParameters.Request(parameters=request),
                                     timeout_sec=ANSWER_TIMEOUT_S)
                if answer is None:
                    self.lost.append((sent, ', '.join(p.name for p in request)))
                    continue
                self.answers.append((sent, time.monotonic() - sent,
                                     all(r.successful for r in answer.results)))
        finally:
            executor.shutdown()
            spinner.join(5.0)
            node.destroy_node()
            rclpy.try_shutdown(context=ctx)

    @staticmethod
    def _matched(client) -> None:
        """
        Wait until a request is answered (an empty one: it changes nothing).

        A service seen in the graph may not yet have matched the client's reply reader; a
        request sent then is never answered (DDS discovery, not the node): not counted.
        """
        end = time.monotonic() + 60.0
        client.wait_for_service(timeout_sec=60.0)
        while time.monotonic() < end:
            if client.call(SetParameters.Request(parameters=[]), timeout_sec=1.0) is not None:
                return
        raise RuntimeError('the node answered no request within 60 s')


def measure(seconds: float, progress: Callable[[str], None]) -> dict:
    """Run the storm for ``seconds`` against a node started here (see the module)."""
    domain = domain_id()
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    args = [str(executable('modal_spring_node')), '--ros-args', '-p', f'scene:={SCENE}',
            '-r', '__ns:=/storm']
    log = tempfile.TemporaryFile(mode='w+')       # the node's log: its errors are reported
    node = subprocess.Popen(args, env=env, stdout=subprocess.DEVNULL, stderr=log,
                            start_new_session=True)
    ctx = Context()
    rclpy.init(context=ctx, domain_id=domain)
    watcher = rclpy.create_node('storm_watcher', context=ctx)
    frames: list[float] = []
    watcher.create_subscription(PointCloud2, '/storm/points',
                                lambda m: frames.append(time.monotonic()), 10)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(watcher)
    memory: list[tuple[float, float]] = []
    try:
        ready = time.monotonic() + 120.0
        while not frames and time.monotonic() < ready and node.poll() is None:
            executor.spin_once(timeout_sec=0.1)
        if not frames:
            raise RuntimeError('the node did not stream within 120 s')
        start = time.monotonic()
        end = start + seconds
        clients = [_Client(i, domain, end) for i in range(CLIENTS)]
        for client in clients:
            client.start()
        next_sample = start
        while time.monotonic() < end:
            executor.spin_once(timeout_sec=0.05)
            if time.monotonic() >= next_sample:
                rss = _node_rss_mb(node.pid)
                if rss is not None:
                    memory.append((time.monotonic() - start, rss))
                next_sample += MEMORY_PERIOD_S
                sent = sum(len(c.answers) for c in clients)
                if len(memory) % 12 == 1:
                    progress(f'storm: {time.monotonic() - start:.0f} of {seconds:.0f} s, '
                             f'{sent} answers, node {rss or 0:.0f} MB')
        alive = bool(frames) and time.monotonic() - frames[-1] < 2.0
        for client in clients:
            client.join(ANSWER_TIMEOUT_S + 10.0)
    finally:
        executor.shutdown()
        watcher.destroy_node()
        rclpy.try_shutdown(context=ctx)
        end_node(node)
    answers = sorted((sent - start, took, ok) for c in clients for sent, took, ok in c.answers)
    lost = sorted((sent - start, what) for c in clients for sent, what in c.lost)
    log.seek(0)
    errors = [line.rstrip() for line in log if 'ERROR' in line or 'Traceback' in line]
    log.close()
    return dict(summary(answers, lost, memory, seconds, alive), node_errors=errors[:20])


def summary(answers: list[tuple[float, float, bool]], lost: list[tuple[float, str]],
            memory: list[tuple[float, float]], seconds: float, alive: bool) -> dict:
    """
    Return the storm's figures.

    From its answers (at, seconds, accepted), the requests never answered (at, parameters) and
    the memory samples (at, MB).
    """
    took = np.array([a[1] for a in answers]) if answers else np.zeros(0)
    after = min(SETTLED_S, seconds / 3.0)        # a short storm: after its first third
    settled = [(t, mb) for t, mb in memory if t >= after]
    growth = (float(np.polyfit([t for t, _ in settled], [mb for _, mb in settled], 1)[0]) * 60.0
              if len(settled) >= 3 else float('nan'))
    return {
        'scene': SCENE, 'clients': CLIENTS, 'seconds': seconds,
        'requests': len(answers) + len(lost), 'lost': len(lost),
        'lost_requests': [[round(t, 2), what] for t, what in lost],
        'refused': sum(1 for a in answers if not a[2]),
        'answer_median_s': float(np.median(took)) if took.size else float('nan'),
        'answer_p99_s': float(np.percentile(took, 99)) if took.size else float('nan'),
        'answer_max_s': float(took.max()) if took.size else float('nan'),
        'share_over_1s': float(np.mean(took > SLOW_ANSWER_S)) if took.size else float('nan'),
        'settled_after_s': after,
        'memory_settled_mb': settled[0][1] if settled else float('nan'),
        'memory_end_mb': memory[-1][1] if memory else float('nan'),
        'memory_growth_mb_per_min': growth, 'streaming_at_end': alive,
        'answers': [[round(a[0], 3), round(a[1], 5)] for a in answers],
        'memory': [[round(t, 1), round(mb, 2)] for t, mb in memory],
    }


def run(quick: bool, progress: Callable[[str], None]) -> dict:
    seconds = QUICK_DURATION_S if quick else DURATION_S
    progress(f'storm: {CLIENTS} clients for {seconds:.0f} s on {SCENE}')
    return measure(seconds, progress)


def table(results: dict) -> str:
    r = results
    return '\n'.join([
        f"{r['clients']} clients, {r['seconds']:.0f} s on {r['scene']}: {r['requests']} "
        f"requests, {r['lost']} unanswered, {r['refused']} refused as they should be",
        f"answer time: median {1e3 * r['answer_median_s']:.1f} ms, p99 "
        f"{1e3 * r['answer_p99_s']:.1f} ms, worst {r['answer_max_s']:.2f} s, "
        f"{100 * r['share_over_1s']:.2f} % over {SLOW_ANSWER_S:g} s",
        f"node memory: {r['memory_settled_mb']:.0f} MB after {r['settled_after_s']:.0f} s, "
        f"{r['memory_end_mb']:.0f} MB at the end ({r['memory_growth_mb_per_min']:+.2f} MB/min "
        f"fitted from then on); streaming at the end: {r['streaming_at_end']}",
        f"node log: {len(r.get('node_errors', []))} errors"
        + ''.join(f'\n  {line[:160]}' for line in r.get('node_errors', [])[:3])])


def write_outputs(results: dict, out, progress) -> None:
    """Draw the answer times and the node's memory over the storm (``storm.png``)."""
    fig, (top, bottom) = subplots(2, 1, figsize=(8, 6), sharex=True)
    answers = np.array(results['answers']).reshape(-1, 2)
    top.plot(answers[:, 0], answers[:, 1] * 1e3, '.', ms=2, alpha=0.4, label='answer')
    top.axhline(SLOW_ANSWER_S * 1e3, color='C3', lw=1, label=f'{SLOW_ANSWER_S:g} s')
    top.set_yscale('log')
    top.set_ylabel('answer time (ms)')
    top.set_title(f"{results['clients']} clients storming {results['scene']}'s parameters: "
                  f"p99 {1e3 * results['answer_p99_s']:.0f} ms")
    top.legend(fontsize=8)
    memory = np.array(results['memory']).reshape(-1, 2)
    bottom.plot(memory[:, 0], memory[:, 1], 'k-')
    bottom.axvline(results['settled_after_s'], color='0.6', lw=1, ls='--')
    bottom.set_xlabel('time into the storm (s)')
    bottom.set_ylabel('node memory, RSS (MB)')
    fig.tight_layout()
    path = out / 'storm.png'
    fig.savefig(path, dpi=110)
    progress(f'wrote {path}')

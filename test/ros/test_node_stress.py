"""
The stream cannot die silently.

Band changes every 20 ms, reset and pause every 30 ms and method switches, all at once for 20 s,
over real DDS against the real node process.
"""
from __future__ import annotations

import threading
import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from helpers import random_band
import numpy as np
import pytest
from ros_harness import node_of, node_with_client, wait_for
from sensor_msgs.msg import PointCloud2
from std_srvs.srv import SetBool, Trigger

pytestmark = [pytest.mark.ros, pytest.mark.slow]

NODE = 'stress20/modal_spring'
DURATION_S = 20.0
#: each kind of request is sent at least this often, however long a busy machine takes for it
MIN_EACH = 12
#: the storm ends by this time at the latest (a guard, not a measurement)
LONGEST_S = 150.0


def stamp_s(msg) -> float:
    """Return a message's header stamp in seconds."""
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


BANDS = [('lowpass', 0.0, 12.0), ('highpass', 10.0, 11.0), ('bandpass', 5.0, 40.0),
         ('bandstop', 8.0, 30.0), ('allpass', 0.0, 1.0)]


def test_concurrent_band_reset_pause_and_method_changes_keep_the_stream_whole():
    # frames stamped with the node's clock when it publishes: gaps are the node's, not the
    # delays of this busy test process receiving them
    with node_with_client('stamp:=wall', namespace='stress20') as (node, client):
        points = client.collect(PointCloud2, '/stress20/points', qos=1000)
        diagnostics = client.collect(DiagnosticArray, '/diagnostics')
        assert wait_for(lambda: len(points) > 3, 30)
        quiet = time.monotonic()
        time.sleep(3.0)                              # the steady stream on this machine
        steady = np.diff([stamp_s(m) for t, m in points if t >= quiet])
        answered = {'band': 0, 'reset': 0, 'pause': 0, 'method': 0}
        sent = dict.fromkeys(answered, 0)
        failures: list[str] = []
        busy: list[str] = []   # answered "not applied in time": an answer, counted apart
        end = time.monotonic() + DURATION_S
        last = time.monotonic() + LONGEST_S

        def repeat(kind, period_s, call):
            k = 0
            # for DURATION_S, and on until this kind was sent MIN_EACH times (a slow machine
            # answers fewer in the same time: the count, not the clock, says what was tested)
            while (time.monotonic() < end or k < MIN_EACH) and time.monotonic() < last:
                sent[kind] += 1
                try:
                    ok, why = call(k)
                except TimeoutError as exc:  # unanswered: counted, reported below
                    failures.append(f'{kind}: {exc}')
                else:
                    answered[kind] += 1
                    if not ok and why.startswith('not applied in time'):
                        busy.append(f'{kind}: {why}')
                    elif not ok:
                        failures.append(f'{kind} refused: {why}')
                k += 1
                time.sleep(period_s)

        def band(k):
            kind, low, high = BANDS[k % len(BANDS)]
            (r,) = client.set_parameters(NODE, atomically=True, timeout=10.0, filter__type=kind,
                                         filter__low_hz=low, filter__high_hz=high)
            return r.successful, r.reason

        def reset(k):
            r = client.call(Trigger, f'/{NODE}/reset', Trigger.Request(), timeout=10.0)
            return r.success, r.message

        pauses = []  # (sent, answered, paused?)

        def pause(k):
            t0 = time.monotonic()
            r = client.call(SetBool, f'/{NODE}/pause', SetBool.Request(data=k % 2 == 0),
                            timeout=10.0)
            pauses.append((t0, time.monotonic(), k % 2 == 0))
            return r.success, r.message

        def method(k):
            (r,) = client.set_parameters(NODE, timeout=10.0, method=('full', 'modal')[k % 2])
            return r.successful, r.reason

        # one client per service, matched before the storm starts
        client.call(Trigger, f'/{NODE}/reset', Trigger.Request())
        client.call(SetBool, f'/{NODE}/pause', SetBool.Request(data=False))
        client.set_parameters(NODE, atomically=True, filter__type='allpass')
        client.set_parameters(NODE, method='modal')
        start = time.monotonic()
        workers = [threading.Thread(target=repeat, args=args) for args in (
            ('band', 0.02, band), ('reset', 0.03, reset), ('pause', 0.03, pause),
            ('method', 0.5, method))]
        for w in workers:
            w.start()
        for w in workers:
            w.join()
        client.call(SetBool, f'/{NODE}/pause', SetBool.Request(data=False))
        after = time.monotonic()
        assert wait_for(lambda: len([t for t, _ in points if t > after]) > 30, 10)
        assert node.proc.poll() is None
        assert failures == []
        # a reset or pause queued behind rebuilds on a loaded host may be answered "not applied
        # in time" (after SERVICE_TIMEOUT_S): an answer, but rare
        assert len(busy) <= 0.05 * (sent['reset'] + sent['pause']), busy
        assert answered == sent and min(sent.values()) >= MIN_EACH, (sent, answered)
        # gaps while the stream runs (a pause, from its request to the answer of the next
        # resume, is the user's stop, not a stall)
        paused = [(sent_at, pauses[i + 1][1] if i + 1 < len(pauses) else after)
                  for i, (sent_at, _, data) in enumerate(pauses) if data]
        frames = [(t, stamp_s(m)) for t, m in points if t >= start]
        running_gaps = [sb - sa for (a, sa), (b, sb) in zip(frames, frames[1:])
                        if not any(p0 < b and a < p1 for p0, p1 in paused)]
        # no stall: the longest running gap within what the steady stream's longest allows
        longest = 8.0 * max(steady.max(), 1.0 / 60.0)
        assert len(running_gaps) > 30 and max(running_gaps) < longest, (
            max(running_gaps), steady.max())
        for _, m in points:
            assert np.isfinite(np.frombuffer(bytes(m.data), dtype='<f4')).all()
        levels = [d.status[0].level for t, d in diagnostics
                  if t >= start and node_of(d.status[0]).startswith('/stress20/')]
        assert levels and DiagnosticStatus.ERROR not in levels


def _values(diagnostics, prefix: str, after: float) -> dict[str, str]:
    for t, d in reversed(diagnostics):
        if t > after and node_of(d.status[0]).startswith(prefix):
            return {kv.key: kv.value for kv in d.status[0].values}
    return {}


def test_fifty_band_changes_a_second_needing_new_modes_are_answered_without_waiting_for_them():
    """
    Band changes whose modes take long to compute never hold the parameter service.

    ``sheet_32x32`` starts with the modes below 5 Hz; each wider band needs more (hundreds of
    milliseconds to seconds of work each).
    """
    with node_with_client('scene:=sheet_32x32', 'filter.type:=lowpass', 'filter.high_hz:=5.0',
                          'sim.dt:=0.0004', namespace='storm50') as (node, client):
        node_name = 'storm50/modal_spring'
        points = client.collect(PointCloud2, '/storm50/points', qos=1000)
        diagnostics = client.collect(DiagnosticArray, '/diagnostics')
        assert wait_for(lambda: len(points) > 3, 60)
        client.set_parameters(node_name, filter__high_hz=5.0)       # the service matched
        highs = [8.0, 12.0, 20.0, 30.0, 45.0, 60.0, 90.0]
        latencies, refused = [], []
        for k in range(100):                                         # 50 a second for 2 s
            sent = time.monotonic()
            (r,) = client.set_parameters(node_name, timeout=10.0,
                                         filter__high_hz=highs[k % len(highs)])
            latencies.append(time.monotonic() - sent)
            if not r.successful:
                refused.append(r.reason)
            time.sleep(max(0.0, 0.02 - (time.monotonic() - sent)))
        assert refused == []
        # a service held by the computations (each hundreds of milliseconds to seconds) would
        # hold most of the answers queued behind them; a loaded machine stalls a few of any
        slow = [t for t in latencies if t > 1.0]
        assert len(slow) <= 5 and sorted(latencies)[50] < 0.25, sorted(latencies)[-10:]
        last = highs[99 % len(highs)]
        # the latest request is the one the run ends with, and nothing is left pending
        settled = time.monotonic()
        assert wait_for(lambda: (v := _values(diagnostics, '/storm50/', settled)) and
                        v['parameter changes pending'] == 'none' and
                        v['band'].endswith(f'<= {last:g} Hz'), 120)
        assert client.get_parameters(node_name, 'filter.high_hz') == [last]
        assert node.proc.poll() is None and wait_for(
            lambda: len([t for t, _ in points if t > settled]) > 30, 20)


def test_a_band_whose_modes_prove_unstable_after_its_answer_is_reverted_and_reported():
    with node_with_client('scene:=sheet_32x32', 'filter.type:=lowpass', 'filter.high_hz:=5.0',
                          namespace='revert') as (node, client):
        node_name = 'revert/modal_spring'
        diagnostics = client.collect(DiagnosticArray, '/diagnostics')
        points = client.collect(PointCloud2, '/revert/points', qos=100)
        assert wait_for(lambda: len(points) > 3, 60)
        # the step chosen for the modes below 5 Hz cannot step those up to 300 Hz: known only
        # once they are computed (about a second), so answered pending, then set back
        (r,) = client.set_parameters(node_name, filter__high_hz=300.0)
        if r.successful:          # (rclpy drops the reason of a success: pending is not said)
            assert wait_for(lambda: 'reverted' in _values(diagnostics, '/revert/', 0.0).get(
                'parameter changes pending', '') or any(
                    'filter.high_hz=300.0 reverted' in d.status[0].message
                    and d.status[0].level == DiagnosticStatus.WARN
                    for _, d in diagnostics), 60)
        else:                       # a fast machine computed them within the answer's time
            assert 'sim.dt' in r.reason
        assert wait_for(lambda: client.get_parameters(node_name, 'filter.high_hz') == [5.0], 30)
        settled = time.monotonic()
        assert wait_for(lambda: (v := _values(diagnostics, '/revert/', settled)) and
                        v['band'] == 'lowpass <= 5 Hz', 10)
        assert node.proc.poll() is None


def test_a_random_sequence_of_equaliser_changes_keeps_the_stream_finite_and_undiverged():
    """
    Twenty random bands, one every quarter second, as a user turning the knobs sends them.

    Kinds, orders, gains on the output and on the loads, damping ranges.

    Refused ones change nothing; the accepted ones must never diverge the run: no ERROR on
    /diagnostics, every frame finite, the stream on after the last.
    """
    rng = np.random.default_rng(4)    # diverged at its 13th change when gains scaled springs
    with node_with_client(namespace='knobs') as (node, client):
        node_name = 'knobs/modal_spring'
        points = client.collect(PointCloud2, '/knobs/points', qos=1000)
        diagnostics = client.collect(DiagnosticArray, '/diagnostics')
        assert wait_for(lambda: len(points) > 3, 60)
        start = time.monotonic()
        accepted = 0
        for _ in range(20):
            band = random_band(rng, top_hz=50.0)
            (r,) = client.set_parameters(
                node_name, atomically=True, filter__type=band['kind'],
                filter__low_hz=band['low'], filter__high_hz=min(band['high'], 1000.0),
                filter__order=band['order'], filter__gains=' '.join(band['gains']),
                filter__gains_act_on=band['acts_on'], filter__damping=' '.join(band['damping']))
            accepted += r.successful
            time.sleep(0.25)
        after = time.monotonic()
        assert accepted >= 10
        assert wait_for(lambda: len([t for t, _ in points if t > after]) > 30, 20)
        assert node.proc.poll() is None
        for t, m in points:
            assert np.isfinite(np.frombuffer(bytes(m.data), dtype='<f4')).all()
        statuses = [d.status[0] for t, d in diagnostics
                    if t >= start and node_of(d.status[0]).startswith('/knobs/')]
        assert statuses and all(s.level != DiagnosticStatus.ERROR for s in statuses), [
            s.message for s in statuses if s.level == DiagnosticStatus.ERROR][:3]

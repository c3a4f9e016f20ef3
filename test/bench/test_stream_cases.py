"""The stream benchmark picks its cases and its DDS domain as a user asks (no node started)."""
from __future__ import annotations

from modal_spring_ros.bench.costs import stream
import pytest


def test_one_case_is_picked_by_a_part_of_its_label():
    chosen = stream.select_cases('default transports', quick=False)
    assert [label for label, _, _ in chosen] == [
        'sheet_316x316 (100k), sampled springs, Fast DDS default transports (UDP)']
    assert chosen[0][2][-1] == '--env=FASTDDS_BUILTIN_TRANSPORTS=DEFAULT'
    assert len(stream.select_cases('100K', quick=False)) == 5          # any case
    assert stream.select_cases(None, quick=True) == stream.CASES[:2]
    with pytest.raises(ValueError, match="--case 'nothing' matches no stream case"):
        stream.select_cases('nothing', quick=False)


def test_the_domain_is_ros_domain_id_when_set(monkeypatch):
    monkeypatch.setenv('ROS_DOMAIN_ID', '42')
    assert stream.domain_id() == 42
    monkeypatch.delenv('ROS_DOMAIN_ID')
    assert 110 <= stream.domain_id() <= 200
    monkeypatch.setenv('ROS_DOMAIN_ID', '300')
    with pytest.raises(ValueError, match=r"ROS_DOMAIN_ID \('300'\) must be a whole number"):
        stream.domain_id()


def _result(label: str, wall: float, cpu: float) -> dict:
    return {'label': label, 'particles': 99856, 'rate_hz': 60.0, 'latency_median_ms': 1.0,
            'latency_p95_ms': 2.0, 'achieved_rtf': 1.0, 'step_us': 20.0,
            'first_frame_s': wall, 'first_frame_cpu_s': cpu}


def test_the_start_up_is_a_ratio_against_the_same_run_s_baseline():
    assert {stream.EARLY, stream.WAITING} <= {label for label, _, _ in stream.CASES}
    (early,) = [p for label, _, p in stream.CASES if label == stream.EARLY]
    (waiting,) = [p for label, _, p in stream.CASES if label == stream.WAITING]
    assert waiting == early + ['stream_early:=false']
    text = stream.table([_result(stream.EARLY, 9.0, 10.0), _result(stream.WAITING, 18.0, 25.0)])
    assert text.splitlines()[-1] == (
        'start-up of the 100k sheet: the first frame after 10.0 s of CPU streaming early, '
        '25.0 s waiting for every mode: 2.50x less (2.00x in wall time)')
    assert 'start-up' not in stream.table([_result(stream.EARLY, 9.0, 10.0)])


def test_the_busy_case_runs_beside_two_busy_processes_and_is_a_ratio_to_the_quiet_one():
    (busy,) = [p for label, _, p in stream.CASES if label == stream.BUSY_CASE]
    (quiet,) = [p for label, _, p in stream.CASES if label == stream.QUIET_CASE]
    assert busy == quiet + [f'{stream.BUSY}2']
    slow = dict(_result(stream.BUSY_CASE, 3.0, 4.0), rate_hz=45.0, achieved_rtf=0.75,
                latency_median_ms=3.0)
    text = stream.table([_result(stream.QUIET_CASE, 3.0, 4.0), slow])
    assert text.splitlines()[-1] == (
        'beside two busy processes the 10k sheet streams at 0.75x the quiet rate, real-time '
        'factor 0.75 (quiet 1.00), median latency 3.0x')

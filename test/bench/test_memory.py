"""The memory estimate bounds the peak a run really reaches, measured in a process of its own."""
from __future__ import annotations

from modal_spring_ros.bench.costs.memory import measure_in_child
from modal_spring_ros.core.filter_band import FilterBand
import pytest

#: the node's kind of run on a large scene, narrowed to the 15 lowest modes and their
#: derivative coordinates (the default coordinates)
CONFIG = {'band': FilterBand('lowpass', 0, 14, 'index')}


@pytest.mark.timeout(400)
@pytest.mark.parametrize('kind, side', [('sheet', 60), ('sheet', 100), ('sheet', 140),
                                        ('block', 11)])
@pytest.mark.slow
def test_the_estimate_bounds_the_measured_peak_within_one_and_a_half(kind, side):
    result = measure_in_child(kind, side, CONFIG)
    assert result['peak_mb'] > 20.0  # a real run was measured
    assert 1.0 <= result['estimate_over_peak'] <= 1.5, result


@pytest.mark.slow
@pytest.mark.timeout(400)
def test_the_estimate_bounds_a_run_with_every_mode_up_to_the_cap_and_sampled_springs():
    wide = measure_in_child('sheet', 50, {})   # allpass: 256 modes and their derivatives
    sampled = measure_in_child('sheet', 70, dict(CONFIG, basis='rest', forces='sampled'))
    for result in (wide, sampled):
        assert 1.0 <= result['estimate_over_peak'] <= 1.5, result

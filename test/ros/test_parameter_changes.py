"""A band that keeps no mode is refused at once where the modes computed already decide it."""
from __future__ import annotations

from modal_spring_ros.core.bases.basis import ModalBasis
from modal_spring_ros.core.filter_band import FilterBand
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.ros.changes.parameter_changes import ChangePlanner
from modal_spring_ros.scenes.resources import load_scene
import pytest


@pytest.fixture(scope='module')
def planner() -> ChangePlanner:
    model = MassSpringModel(load_scene('sheet_32x32'))
    basis = ModalBasis(model)
    basis.ensure_count(20)                 # the lowest 20 of 1,984 modes: not all of them
    assert not basis.complete
    return ChangePlanner(model, basis)


def gap(planner: ChangePlanner) -> tuple[float, float]:
    """Return the widest gap between two computed modes, Hz."""
    f = planner.basis.frequencies_hz
    i = int((f[1:] - f[:-1]).argmax())
    return float(f[i]), float(f[i + 1])


def test_a_band_between_two_computed_modes_or_below_the_lowest_is_refused_at_once(planner):
    f = planner.basis.frequencies_hz
    below, above = gap(planner)
    middle = FilterBand('bandpass', low=below + 0.3 * (above - below),
                        high=above - 0.3 * (above - below))
    assert planner.keeps_no_mode(middle).startswith(
        f'filter band {middle.describe()} keeps no mode (none of the modes from '
        f'{f[0]:.4g} to {f[-1]:.4g} Hz is in it)')
    low = FilterBand('lowpass', high=0.5 * f[0])
    assert 'keeps no mode (the modes up to' in planner.keeps_no_mode(low)


def test_what_modes_not_yet_computed_could_fill_is_left_to_the_change(planner):
    """Above the highest mode computed, the change computes more (it may keep some)."""
    f = planner.basis.frequencies_hz
    below, above = gap(planner)
    assert planner.keeps_no_mode(FilterBand('bandpass', low=f[-1] + 1.0,
                                            high=f[-1] + 50.0)) == ''   # above: not computed
    assert planner.keeps_no_mode(FilterBand('highpass', low=f[-1] + 1.0)) == ''
    assert planner.keeps_no_mode(FilterBand('bandpass', low=below - 0.01,
                                            high=above + 0.01)) == ''   # keeps two
    assert planner.keeps_no_mode(FilterBand('bandstop', low=0.0, high=f[-1] + 1.0)) == ''
    assert planner.keeps_no_mode(FilterBand('lowpass', by='index', high=0)) == ''

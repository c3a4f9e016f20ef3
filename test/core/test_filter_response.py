"""
The filter's response (a modal equaliser): rounded edges, gains in dB, where they act, damping.

Each gain is measured from the run's own modal coordinates: a shown displacement projected on
mode ``k`` (``phi_k^T M u``) over the same run's physical one.
"""
from __future__ import annotations

import math

from helpers import variant
from modal_spring_ros.core.config import ConfigError, SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.filter_band import BandError, FilterBand
from modal_spring_ros.core.filter_response import butterworth, GAIN_FLOOR
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest

DOUBLE_DB = 20.0 * math.log10(2.0)


@pytest.fixture(scope='module')
def sheet():
    return load_scene('sheet_10x10')


def num(x) -> str:
    """Return ``x`` as a gain term writes it (every digit kept)."""
    return repr(float(x))


def run(scene, band: FilterBand, steps: int = 400, basis: str = 'rest', **config):
    sim = build_simulation(scene, SimulationConfig(band=band, basis=basis, **config))
    sim.step(steps)
    return sim


def mode_amplitudes(sim, modes: np.ndarray, steps: int, every: int = 5):
    """Return (shown, physical) projections on ``modes`` over the next ``steps`` steps."""
    phi = sim.basis.vectors[:, modes]
    m = sim.model.mass_dof
    shown, physical = [], []
    for _ in range(steps // every):
        sim.step(every)
        shown.append(phi.T @ (m * sim.shown_displacement()))
        physical.append(phi.T @ (m * sim.displacement()))
    return np.array(shown), np.array(physical)


@pytest.mark.parametrize('order', [1, 2, 4, 8])
def test_a_mode_at_the_edge_of_a_butterworth_lowpass_is_at_minus_3_db(sheet, order):
    probe = run(sheet, FilterBand(), steps=0)
    k = 6
    edge = float(probe.basis.frequencies_hz[k])
    sim = run(sheet, FilterBand('lowpass', 0.0, edge, order=order), steps=200)
    shown, physical = mode_amplitudes(sim, np.array([k]), 400)
    ratio = np.abs(shown).max() / np.abs(physical).max()
    assert 20 * math.log10(ratio) == pytest.approx(-10 * math.log10(2.0), abs=1e-9)
    # and the modes far above the edge are rolled off by order * 20 dB a decade
    f = probe.basis.frequencies_hz
    assert butterworth('lowpass', 0.0, edge, order, np.array([10 * edge]))[0] == pytest.approx(
        1 / math.sqrt(1 + 100.0 ** order), rel=1e-9)
    assert sim.coordinates == int(np.sum(f <= FilterBand('lowpass', 0.0, edge,
                                                         order=order).top))


def test_a_6_db_peak_doubles_its_mode_s_output_and_leaves_the_motion_as_it_was(sheet):
    plain = run(sheet, FilterBand(), steps=300)
    k = 4
    f = plain.basis.frequencies_hz
    width = 0.2 * (f[k + 1] - f[k - 1])
    peak = f'peak:{num(f[k])}:{num(width)}:{num(DOUBLE_DB)}'
    sim = run(sheet, FilterBand(gains=(peak,)), steps=300)
    np.testing.assert_allclose(sim.displacement(), plain.displacement(), rtol=0, atol=1e-15)
    shown, physical = mode_amplitudes(sim, np.array([k - 1, k, k + 1]), 300)
    gains = np.abs(shown).max(axis=0) / np.abs(physical).max(axis=0)
    assert gains[1] == pytest.approx(2.0, rel=1e-9)
    expected = 10 ** (DOUBLE_DB / (1 + ((f[[k - 1, k + 1]] - f[k]) / (0.5 * width)) ** 2) / 20)
    np.testing.assert_allclose(gains[[0, 2]], expected, rtol=1e-9)


def test_ranges_and_shelves_add_in_db(sheet):
    band = FilterBand(gains=('2:6:-6', 'low_shelf:4:12', 'high_shelf:4:-12')).validate()
    f = np.array([0.0, 2.0, 4.0, 6.0, 100.0])
    db = 20 * np.log10(band.gain(f))
    shelf = 12 * 16 / (16 + f ** 2) - 12 * f ** 2 / (16 + f ** 2)
    np.testing.assert_allclose(db, shelf + np.where((f >= 2) & (f <= 6), -6, 0), atol=1e-9)


def test_output_gains_leave_the_added_coordinates_as_computed(sheet):
    band = FilterBand('lowpass', 0, 14, 'index', gains=(f'0:1000:{num(DOUBLE_DB)}',))
    sim = run(sheet, band, steps=300, basis='derivatives')
    rest = sim.kept_modes
    q = sim.modal_coordinates
    phi = sim.basis.vectors[:, rest]
    np.testing.assert_allclose(sim.shown_displacement() - sim.displacement(),
                               phi @ q[:rest.size], rtol=1e-9, atol=1e-15)
    assert sim.coordinates > rest.size


def test_a_load_gain_scales_a_mode_s_static_response():
    """A still clamp, heavily damped (settles in a second), small sag: the linear regime."""
    sheet = variant('sheet_10x10', anchor_motion=[])
    probe = run(sheet, FilterBand(), steps=0)
    f = probe.basis.frequencies_hz
    k = int(np.argmax(np.abs(probe.basis.vectors.T @ probe.model.gravity_force)))
    damped = ('0:1000:0.7',)
    lo, hi = 0.5 * (f[k - 1] + f[k]) if k else 0.0, 0.5 * (f[k] + f[k + 1])
    plain = run(sheet, FilterBand(damping=damped), steps=20000)
    gain = f'{num(lo)}:{num(hi)}:{num(DOUBLE_DB)}'
    loaded = run(sheet, FilterBand(gains=(gain,), acts_on='load', damping=damped), steps=20000)
    q0, q1 = plain.modal_coordinates, loaded.modal_coordinates
    assert q1[k] / q0[k] == pytest.approx(2.0, rel=0.01)
    others = np.delete(np.arange(q0.size), k)
    assert np.abs(q1[others] - q0[others]).max() < 0.02 * np.abs(q0[k])
    np.testing.assert_allclose(loaded.shown_displacement(), loaded.displacement())


@pytest.mark.parametrize('ratio', [0.02, 0.1])
def test_a_damping_range_gives_its_mode_the_requested_decay(ratio):
    scene = variant('sheet_10x10', gravity=[0.0, 0.0, 0.0], anchor_motion=[])
    k = 3
    sim = run(scene, FilterBand(), steps=0)
    f = sim.basis.frequencies_hz
    band = FilterBand(damping=(f'{num(f[k] * 0.999)}:{num(f[k] * 1.001)}:{num(ratio)}',))
    sim = run(scene, band, steps=0, dt=2e-4)
    shape = sim.basis.vectors[:, k]
    sim.set_state(1e-3 * shape / np.abs(shape).max(), np.zeros_like(shape))
    omega = 2 * math.pi * f[k]
    times, q = [], []
    for _ in range(int(3.0 / (ratio * omega) / 2e-4)):
        sim.step()
        times.append(sim.time)
        q.append(sim.modal_coordinates[k])
    q, times = np.array(q), np.array(times)
    peaks = np.flatnonzero((q[1:-1] > q[:-2]) & (q[1:-1] >= q[2:])) + 1
    rate = -np.polyfit(times[peaks], np.log(q[peaks]), 1)[0]
    assert rate / omega == pytest.approx(ratio, rel=0.05)    # q ~ exp(-h omega t)


def test_a_gain_change_while_running_fades_with_no_jump(sheet):
    def frame_steps(transition_s: float) -> tuple[float, float]:
        sim = run(sheet, FilterBand(), steps=500, transition_s=transition_s)
        frames = [sim.shown_displacement()]
        sim.set_band(FilterBand(gains=('0:1000:12',)))
        for _ in range(int(0.5 / sim.dt) + 400):
            sim.step()
            frames.append(sim.shown_displacement())
        change = np.abs(np.diff(frames, axis=0)).max(axis=1)
        settled = int(0.5 / sim.dt) + 1
        return change[:settled].max(), change[settled:].max()
    during, after = frame_steps(0.5)
    assert during <= 1.01 * after          # no step larger than ordinary running with the gain
    jump, after_instant = frame_steps(0.0)
    assert jump > 10 * after_instant       # an instant change does jump: the measure sees it


def test_a_rounded_lowpass_steps_the_modes_above_its_edge_down_to_the_floor(sheet):
    band = FilterBand('lowpass', 0.0, 8.0, order=4).validate()
    sim = run(sheet, band, steps=0)
    f = sim.basis.frequencies_hz
    assert sim.coordinates == int(np.sum(band.gain(f) >= GAIN_FLOOR)) > int(np.sum(f <= 8.0))
    assert band.gain(np.array([band.top]))[0] == pytest.approx(GAIN_FLOOR, rel=1e-9)


@pytest.mark.parametrize('band, message', [
    (FilterBand(order=17), 'order (17) must be a whole number from 0'),
    (FilterBand('lowpass', 0, 14, 'index', order=2), "rounds edges in Hz: it needs by 'hz'"),
    (FilterBand('highpass', 0.0, order=2), 'low_hz must be above 0 Hz for a rounded highpass'),
    (FilterBand(gains=('5:2:6',)), 'LOW (5 Hz) must be at least 0 and below HIGH (2 Hz)'),
    (FilterBand(gains=('peak:3:0:6',)), 'CENTER and WIDTH must be above 0 Hz'),
    (FilterBand(gains=('1:2:80',)), '80 dB is beyond +-60 dB'),
    (FilterBand(gains=('1:2:nan',)), 'every number must be finite'),
    (FilterBand(gains=('notch:3:6',)), "'notch' is not one of peak, low_shelf, high_shelf"),
    (FilterBand(gains=('1:2',)), 'must be written LOW:HIGH:DB'),
    (FilterBand(acts_on='input'), "acts_on 'input' must be one of output, load"),
    (FilterBand(damping=('1:2:1.5',)), 'RATIO (1.5) must be from 0 to 1'),
])
def test_an_impossible_response_is_refused_with_its_reason(band, message):
    with pytest.raises(BandError) as error:
        band.validate()
    assert message in str(error.value)


def test_a_shape_needs_a_modal_run_without_the_automatic_choice():
    shaped = FilterBand(gains=('1:2:6',))
    with pytest.raises(ConfigError, match='acts on modes: it needs method modal'):
        SimulationConfig(method='full', band=shaped).validate()
    with pytest.raises(ConfigError, match='needs auto off'):
        SimulationConfig(auto=True, band=shaped).validate()


def test_a_shaped_band_survives_the_config_s_round_trip():
    config = SimulationConfig(band=FilterBand('lowpass', 0.0, 9.0, order=3, gains=('1:2:6',),
                                              acts_on='load', damping=('0:3:0.1',)))
    again = SimulationConfig.from_dict(config.to_dict())
    assert again == config and again.band.gains == ('1:2:6',)


@pytest.mark.parametrize('kind, edges', [('lowpass', [9.0]), ('highpass', [3.0]),
                                         ('bandpass', [3.0, 9.0]), ('bandstop', [3.0, 9.0])])
@pytest.mark.parametrize('order', [1, 3, 6])
def test_every_rounded_edge_is_at_minus_3_db_and_its_skirt_falls_with_the_order(
        kind, edges, order):
    band = FilterBand(kind, 3.0, 9.0, order=order).validate()
    np.testing.assert_allclose(band.gain(np.array(edges)), 1 / math.sqrt(2), rtol=1e-12)
    inside = {'lowpass': 0.5, 'highpass': 60.0, 'bandpass': math.sqrt(27.0), 'bandstop': 5.0}
    outside = {'lowpass': 90.0, 'highpass': 0.3, 'bandpass': 90.0, 'bandstop': 90.0}
    kept, cut = band.gain(np.array([inside[kind], outside[kind]]))
    if kind == 'bandstop':     # its pass band is outside the edges
        kept, cut = cut, kept
    assert kept > 0.95 and cut < 1.01 * 0.1 ** order     # a decade out: order x 20 dB down

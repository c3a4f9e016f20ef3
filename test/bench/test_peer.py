"""The peer suite: Newton's semi-implicit run of a scene, and the figure it is compared by."""
from __future__ import annotations

import math

from helpers import variant
from modal_spring_ros.bench.peers import newton_peer, peer
from modal_spring_ros.core.auto.measured_error import on_samples, trajectory, trajectory_error
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.scenes.resources import load_scene
from modal_spring_ros.scenes.schema import scene_from_dict
import numpy as np
import pytest

needs_newton = pytest.mark.skipif(not newton_peer.AVAILABLE, reason=newton_peer.MISSING)


def _row(run, error, cpu, dt=1e-3):
    return {'run': run, 'coordinates': 10, 'dt': dt, 'error': error, 'cpu_per_s': cpu}


def test_the_figure_is_newtons_cheapest_run_within_against_ours_at_its_error_or_better():
    rows = [_row('newton', 0.004, 0.30, 6e-4), _row('newton', 0.002, 0.60, 3e-4),
            _row('newton', 0.03, 0.15, 1.2e-3),          # cheaper, over the tolerance
            _row('full', 0.0005, 0.20), _row('auto', 0.006, 0.01),  # cheap, worse than Newton
            _row('16 modes', 0.0035, 0.05), _row('32 modes', 0.001, 0.08)]
    fig = peer.figure(rows)
    assert fig['peer_run']['dt'] == 6e-4
    assert fig['ours']['run'] == '16 modes'
    assert fig['ratio'] == pytest.approx(6.0)
    assert fig['goal_met']
    assert peer.figure(rows[2:3]) == {}                  # Newton never within: no figure
    fig = peer.figure([rows[0], rows[4]])
    assert fig['ours'] is None and 'ratio' not in fig
    line = peer._figure_line({'figure': fig, 'peer_note': '', 'tolerance': 0.01})
    assert 'no run of the project at that error or better' in line


def test_scenes_the_peer_cannot_run_as_the_project_does_are_refused_with_the_reason():
    assert newton_peer.refusal(load_scene('sheet_32x32_resonance')) == ''
    assert 'modal damping ratio' in newton_peer.refusal(load_scene('sheet_10x10_resonance'))
    assert 'clamp turns' in newton_peer.refusal(load_scene('sheet_10x10_swing'))
    line = peer._figure_line({'figure': {}, 'peer_note': newton_peer.MISSING, 'tolerance': 0.01})
    assert line == f'  no peer: {newton_peer.MISSING}'


@pytest.mark.skipif(newton_peer.AVAILABLE, reason='Newton is installed')
def test_without_newton_a_peer_run_says_how_to_install_it():
    with pytest.raises(RuntimeError, match=r"pip install '\.\[peer\]'"):
        newton_peer.NewtonRun(load_scene('sheet_32x32_resonance'), 1e-3)


def _damped_oscillator(alpha: float):
    """One mass hung on one spring from rest length, along x, with mass-proportional damping."""
    data = {'name': 'damped oscillator', 'dimension': 1, 'axis': 'x',
            'particles': {'positions': [[0.0, 0.0], [1.0, 0.0]], 'mass': [1.0, 0.25]},
            'springs': {'pairs': [[0, 1]], 'stiffness': 400.0},
            'fixed': {'indices': [0]}, 'gravity': [9.81, 0.0, 0.0],
            'damping': {'rayleigh': {'alpha': alpha, 'beta': 0.0}}}
    return scene_from_dict(data, source='test')


@needs_newton
@pytest.mark.parametrize('alpha', [0.0, 4.0])
def test_newtons_run_of_one_mass_on_one_spring_is_the_analytic_step_response(alpha):
    scene = _damped_oscillator(alpha)
    run = newton_peer.NewtonRun(scene, 2e-5)
    samples, sample_s = 30, 0.01
    got = trajectory(run, sample_s, samples)[:, 0]
    t = sample_s * np.arange(1, samples + 1)
    w0, zeta = math.sqrt(400.0 / 0.25), alpha / (2.0 * math.sqrt(400.0 / 0.25))
    wd = w0 * math.sqrt(1.0 - zeta ** 2)
    static = 0.25 * 9.81 / 400.0
    expected = static * (1.0 - np.exp(-zeta * w0 * t) * (
        np.cos(wd * t) + zeta / math.sqrt(1.0 - zeta ** 2) * np.sin(wd * t)))
    assert np.linalg.norm(got - expected) / np.linalg.norm(expected) < 2e-3


@needs_newton
def test_newtons_run_of_a_shaken_damped_sheet_matches_the_projects_full_run():
    """Same masses, springs, gravity, clamp and damping: the two runs agree to their steps."""
    scene = variant('sheet_10x10', damping={'rayleigh': {'alpha': 1.5, 'beta': 0.0}})
    sample_s, samples = 0.01, 50
    full = build_simulation(scene, SimulationConfig(method='full'))
    truth = trajectory(on_samples(full, sample_s, full.stability_limit() / 16), sample_s,
                       samples)
    newton_coarse = trajectory(newton_peer.NewtonRun(scene, sample_s / 20), sample_s, samples)
    newton_fine = trajectory(newton_peer.NewtonRun(scene, sample_s / 80), sample_s, samples)
    coarse, fine = trajectory_error(newton_coarse, truth), trajectory_error(newton_fine, truth)
    assert fine < 0.01
    assert fine < 0.5 * coarse       # a first-order method converging to the same motion


@needs_newton
def test_newton_replayed_from_its_captured_graph_is_the_same_run_as_launched_step_by_step():
    """
    As a Newton user steps: two steps captured once, replayed; odd steps and resets included.

    The shaken sheet sampled every 5 steps (an odd step after each pair), past the first 1024
    steps the clamp's poses were computed for (a new graph): the same float32 run, bit for bit.
    """
    scene = variant('sheet_10x10', damping={'rayleigh': {'alpha': 1.5, 'beta': 0.0}})
    replayed = newton_peer.NewtonRun(scene, 1e-3)
    launched = newton_peer.NewtonRun(scene, 1e-3, graph=False)
    assert replayed.graph and not launched.graph
    first = trajectory(replayed, 0.005, 300)
    np.testing.assert_array_equal(first, trajectory(launched, 0.005, 300))
    assert np.abs(first).max() > 1e-3 and replayed.steps == 0           # reset after
    np.testing.assert_array_equal(trajectory(replayed, 0.005, 300), first)   # from rest again


def test_the_whole_process_line_says_what_users_pay_on_each_side():
    res = {'processes': {'auto_first_s': 1.31, 'auto_s': 1.14, 'newton_s': 4.01,
                         'ratio': 4.01 / 1.14}}
    (line,) = peer._process_lines(res)
    assert line == ('  whole processes: modal_spring_sim --auto 1.14 s of CPU (1.31 s solving its '
                    "modes), Newton's script 4.01 s: 3.5x cheaper (goal 3x met)")
    assert peer._process_lines({'processes': {}}) == [] == peer._process_lines({})


@needs_newton
@pytest.mark.slow
def test_auto_and_newton_are_costed_as_the_processes_users_run():
    """Half a second of the resonance sheet: both scripts run, their CPU time measured."""
    found = peer.process_figures('sheet_32x32_resonance', 0.5, 6.25e-4)
    assert found['auto_first_s'] > 0.3 and found['auto_s'] > 0.3 and found['newton_s'] > 0.3
    assert found['ratio'] == pytest.approx(found['newton_s'] / found['auto_s'])

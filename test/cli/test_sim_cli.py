"""modal_spring_sim: the .npz a user gets, and clear errors for bad options."""
from __future__ import annotations

import subprocess
import sys

from helpers import HIDE_ROS, sheet_on_a_table, variant
from modal_spring_ros.cli.common import (beside_bar, parse_mode_range, progress_bar,
                                         progress_lines, run_main)
from modal_spring_ros.cli.modal_spring_sim import head_start, main, watched_line
from modal_spring_ros.core.auto.watch.amplification import UNBOUNDED
from modal_spring_ros.core.auto.watch.run_watch import WatchedWindow
from modal_spring_ros.core.bases.basis import ModalBasis
from modal_spring_ros.core.config import SimulationConfig
from modal_spring_ros.core.factory import build_simulation
from modal_spring_ros.core.filter_band import BandError, FilterBand
from modal_spring_ros.core.model.model import MassSpringModel
from modal_spring_ros.core.simulations import FullSimulation
from modal_spring_ros.runs.run import record
from modal_spring_ros.scenes.files.writing import scene_to_yaml
from modal_spring_ros.scenes.resources import load_scene
import numpy as np
import pytest


def test_mode_ranges_reproduce_the_papers_figures():
    assert parse_mode_range('0:14') == FilterBand('lowpass', 0, 14, 'index')
    assert parse_mode_range('2:48') == FilterBand('bandpass', 2, 48, 'index')
    for bad in ('14', 'a:b', '5:2', '-1:3'):
        with pytest.raises(BandError, match='^--modes'):
            parse_mode_range(bad)


def test_run_writes_every_documented_field(tmp_path, capsys):
    out = tmp_path / 'run.npz'
    assert main(['--modes', '0:14', '--duration', '0.1', '--output', str(out), '--quiet']) == 0
    text = capsys.readouterr().out
    assert '15 stepped of 180 computed' in text and 'lowpass modes <= 14' in text
    run = np.load(out)
    scene = load_scene('sheet_10x10')
    assert run['t'].shape == (201,) and run['t'][-1] == pytest.approx(0.1)
    assert run['positions'].shape == (201, 100, 3) and run['positions'].dtype == np.float64
    np.testing.assert_array_equal(run['rest_positions'], scene.rest_positions)
    np.testing.assert_array_equal(run['springs'], scene.springs)
    for key in ('stiffness', 'rest_length', 'mass', 'fixed', 'gravity'):
        np.testing.assert_array_equal(run[key], getattr(scene, key))
    assert float(run['damping_ratio']) == 0.02
    assert float(run['rayleigh_alpha']) == 0.0 and float(run['rayleigh_beta']) == 0.0
    assert run['frequencies_hz'].shape == (180,) and np.all(np.diff(run['frequencies_hz']) >= 0)
    assert run['kept_modes'].tolist() == list(range(15))
    assert float(run['dt']) == 5e-4
    assert np.isfinite(run['positions']).all()
    np.testing.assert_array_equal(run['positions'][0], scene.rest_positions)


def test_same_options_give_bit_identical_runs(tmp_path):
    a, b = tmp_path / 'a.npz', tmp_path / 'b.npz'
    for out in (a, b):
        main(['--filter', 'bandpass', '--low-hz', '8', '--high-hz', '40', '--duration', '0.2',
              '--output', str(out), '--quiet'])
    assert np.array_equal(np.load(a)['positions'], np.load(b)['positions'])


@pytest.mark.parametrize('argv, message', [
    (['--filter', 'bandpass', '--low-hz', '5', '--high-hz', '2'],
     '--low-hz (5) must be below --high-hz (2) for bandpass'),
    (['--filter', 'lowpass'], '--filter lowpass needs --high-hz'),
    (['--filter', 'lowpass', '--high-hz', '1'], 'keeps no mode'),
    (['--modes', '9:3'], "--modes '9:3': need 0 <= FIRST <= LAST"),
    (['--scene', 'no_such_scene'], "unknown scene 'no_such_scene'"),
    (['--dt', '0.01', '--method', 'full'], 'explicit stability limit'),
    (['--dt', '-1'], '--dt (-1.0) must be a finite number of seconds, at least 1e-08 s'),
    (['--output', '/nonexistent/dir/run.npz'], 'folder /nonexistent/dir does not exist'),
    (['--modes', '0:14', '--order', '2'], '--order rounds edges in Hz'),
    (['--gain', '1:2:600'], "--gain: '1:2:600': 600 dB is beyond +-60 dB"),
    (['--gain', 'peak:3:6'], "--gain: 'peak:3:6' must be written peak:CENTER:WIDTH:DB"),
    (['--damping-ratio', '0:2:3'], "--damping-ratio: damping '0:2:3': RATIO (3) must be"),
    (['--method', 'full', '--order', '2', '--filter', 'lowpass', '--high-hz', '9'],
     'a filter shape (--order, --gain, --damping-ratio) acts on modes: it needs --method modal'),
    (['--response-chart', '/nonexistent/r.png'], 'folder /nonexistent does not exist'),
])
def test_bad_options_exit_2_with_a_clear_message(argv, message, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv + ['--duration', '0.01', '--quiet'])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith('modal_spring_sim: error: ') and message in err
    assert 'Traceback' not in err


def test_divergence_is_reported_with_exit_1(tmp_path, capsys):
    out = tmp_path / 'div.npz'
    code = main(['--method', 'full', '--dt', '0.003', '--allow-unstable', '--duration', '2',
                 '--output', str(out), '--quiet'])
    assert code == 1
    assert 'DIVERGED' in capsys.readouterr().out
    run = np.load(out)
    assert 'strain' in str(run['diverged']) and np.isfinite(run['positions']).all()


def test_console_script_runs_as_a_user_would(tmp_path):
    out = tmp_path / 'cli.npz'
    proc = subprocess.run([sys.executable, '-m', 'modal_spring_ros.cli.modal_spring_sim',
                           '--scene',
                           'chain_2', '--duration', '0.5', '--output', str(out)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert 'chain_2' in proc.stdout and out.exists()


def test_auto_option_reports_its_choice(capsys):
    # a 0.05 s run: choosing a plan would cost more than the whole full run
    assert main(['--auto', '--tolerance', '0.05', '--duration', '0.05', '--quiet']) == 0
    out = capsys.readouterr().out
    assert 'method     full physical (180 DOF)' in out
    assert 'measured   full run chosen (the whole full run costs' in out
    assert 'less than choosing and building a plan' in out and "10% of the full run's" in out
    # not budgeted, the plan is chosen and measured
    assert main(['--auto', '--tolerance', '0.05', '--duration', '0.05', '--quiet',
                 '--planning-share', 'none']) == 0
    out = capsys.readouterr().out
    assert 'auto       5 modes up to 20.44 Hz, predicted error 3.26%' in out
    assert 'measured   measured error' in out
    with pytest.raises(SystemExit):
        main(['--auto', '--method', 'full', '--duration', '0.01', '--quiet'])
    assert '--auto chooses modes' in capsys.readouterr().err


def test_progress_comes_at_whole_percents_and_no_more_often_than_asked():
    model = MassSpringModel(load_scene('chain_2'))
    basis = ModalBasis(model)

    def run(**kw):
        seen = []
        record(FullSimulation(model, dt=1e-3, basis=basis), 0.5, on_progress=seen.append, **kw)
        return seen

    every = run(progress_interval_s=0.0)  # 500 steps: a report at each 1 %
    assert every == pytest.approx([k / 100 for k in range(1, 101)])
    assert run() == []  # a run far shorter than the default interval reports nothing


def test_a_run_not_written_keeps_its_last_frame_only_and_ends_where_a_kept_one_does():
    """Frames nobody keeps are not held: the 10k sheet over 10 s at every step is 21 GB."""
    model = MassSpringModel(load_scene('sheet_10x10'))
    basis = ModalBasis(model)
    kept = record(FullSimulation(model, dt=1e-3, basis=basis), 0.2)
    seen = []
    streamed = record(FullSimulation(model, dt=1e-3, basis=basis), 0.2, keep_frames=False,
                      on_frame=lambda t, p: seen.append(t))
    alone = record(FullSimulation(model, dt=1e-3, basis=basis), 0.2, keep_frames=False)
    assert kept.t.size == kept.frames_made == 201
    np.testing.assert_array_equal(seen, kept.t)           # every frame still seen
    for run in (streamed, alone):
        assert run.t.size == 1 and run.frames_made == 201
        assert run.t[0] == kept.t[-1]
        np.testing.assert_array_equal(run.positions[0], kept.positions[-1])


def test_a_short_run_prints_no_progress_lines(tmp_path):
    proc = subprocess.run([sys.executable, '-m', 'modal_spring_ros.cli.modal_spring_sim',
                           '--scene',
                           'chain_2', '--duration', '0.05', '--output', str(tmp_path / 'o.npz')],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert '%' not in proc.stderr


def test_a_long_run_shows_a_bar_with_the_time_left_and_a_quiet_one_nothing(capsys):
    """The bar (tqdm) counts simulated seconds and ends where the run ended (a divergence)."""
    show = progress_bar('modal_spring_sim', 4.0, 's', 'simulated', delay_s=0.0)
    show(1.0)
    show(2.5, final=True)                     # the run stopped there
    show(3.0)                                 # nothing after the end
    err = capsys.readouterr().err
    assert '[modal_spring_sim] simulated:  62%' in err
    assert '2.5/4 s [' in err and '<' in err   # elapsed < time left
    assert '3/4' not in err
    quiet = progress_bar('modal_spring_sim', 4.0, 's', 'simulated', quiet=True, delay_s=0.0)
    quiet(4.0, final=True)
    assert capsys.readouterr().err == ''


def test_a_line_beside_a_bar_is_a_line_of_its_own_shown_or_not(capsys):
    """Above a bar shown; plain where the bar waits for its delay (and then shows nothing)."""
    waiting = progress_bar('modal_spring_sim', 4.0, 's', 'simulated', delay_s=60.0)
    waiting(1.0)
    beside_bar('modal_spring_sim', 'WARN: watched')
    waiting(4.0)
    assert capsys.readouterr().err == '[modal_spring_sim] WARN: watched\n'
    shown = progress_bar('modal_spring_sim', 4.0, 's', 'simulated', delay_s=0.0)
    shown(1.0)
    beside_bar('modal_spring_sim', 'WARN: watched')
    shown(4.0)
    lines = capsys.readouterr().err.replace('\r', '\n').split('\n')
    assert '[modal_spring_sim] WARN: watched' in lines
    assert lines[-1] == '' and '4/4 s' in lines[-2]          # the bar ends on its own line


def test_a_benchmark_s_counted_jobs_say_the_time_they_have_left(capsys):
    """At the pace of the jobs counted so far: 2 of 10 in 30 s after the first, 8 left."""
    now = [100.0]
    say = progress_lines('modal_spring_bench', clock=lambda: now[0])
    say('promise 1/10: seed 0 at 1.0%: full')
    now[0] += 30.0
    say('promise 3/10: seed 1 at 1.0%: full')
    say('computing the 32 lowest modes')
    now[0] += 1e4
    say('promise 10/10: seed 4 at 0.3%: full')
    lines = capsys.readouterr().err.splitlines()
    assert lines == ['[modal_spring_bench] promise 1/10: seed 0 at 1.0%: full',
                     '[modal_spring_bench] promise 3/10: seed 1 at 1.0%: full (about 2 min left)',
                     '[modal_spring_bench] computing the 32 lowest modes',
                     '[modal_spring_bench] promise 10/10: seed 4 at 0.3%: full']


def test_finding_the_shape_a_cloth_hangs_in_shows_progress(tmp_path, capsys):
    """cloth_3d is taken about the shape it hangs in (seconds of Newton steps on larger cloths)."""
    assert main(['--scene', 'cloth_3d', '--duration', '0.01', '--basis', 'rest', '--modes', '0:9',
                 '--output', str(tmp_path / 'cloth.npz')]) == 0
    err = capsys.readouterr().err
    assert '[modal_spring_sim] loaded shape: step 10,' in err
    assert '[modal_spring_sim] loaded shape found in' in err
    assert err.index('loaded shape found in') < err.index('modes')   # before the modes


@pytest.mark.slow
def test_without_ros_it_runs_and_says_what_a_bag_would_need(tmp_path):
    """Without the ros extra: runs and ``.npz`` output work, and ``--bag`` says why it cannot."""
    def sim(*args):
        code = HIDE_ROS + ('import sys; from modal_spring_ros.cli.modal_spring_sim import main; '
                           f'sys.exit(main({list(args)!r}))')
        return subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                              timeout=300)
    out = tmp_path / 'run.npz'
    done = sim('--scene', 'cloth_3d', '--duration', '0.05', '--quiet', '--output', str(out))
    assert done.returncode == 0, done.stderr[-2000:]
    assert np.load(out)['positions'].shape[1:] == (400, 3)
    refused = sim('--duration', '0.05', '--bag', str(tmp_path / 'bag'))
    assert refused.returncode == 2
    assert refused.stderr.strip().splitlines()[-1] == (
        'modal_spring_sim: error: --bag needs the ROS message packages (rcl_interfaces is not '
        "installed): pip install '.[ros]' (ROS 2 Jazzy from PyPI wheels), or source a ROS 2 "
        'install')
    assert not (tmp_path / 'bag').exists()


def test_an_equalised_run_streams_its_gains_and_draws_its_response(tmp_path, capsys):
    """
    A +6.02 dB output gain over every rest mode doubles every frame's displacement, exactly.

    (A still clamp: the clamp's own motion is not a mode's.)
    """
    plain, loud, chart = tmp_path / 'plain.npz', tmp_path / 'loud.npz', tmp_path / 'r.png'
    scene = tmp_path / 'still.yaml'
    scene.write_text(scene_to_yaml(variant('sheet_10x10', anchor_motion=[])))
    common = ['--scene', str(scene), '--modes', '0:14', '--basis', 'rest', '--duration', '0.2',
              '--quiet']
    assert main(common + ['--output', str(plain)]) == 0
    assert main(common + ['--output', str(loud), '--gain', '0:1000:6.020599913279624',
                          '--response-chart', str(chart)]) == 0
    assert 'output gains 0:1000:6.020599913279624' in capsys.readouterr().out
    a, b = np.load(plain), np.load(loud)
    rest = a['rest_positions']
    np.testing.assert_allclose(b['positions'] - rest, 2.0 * (a['positions'] - rest), rtol=1e-9,
                               atol=1e-12)
    assert chart.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n' and chart.stat().st_size > 10_000


def ramped_shake(tmp_path):
    """
    Return a scene file: ``sheet_10x10`` shaken near its vertical mode, growing over 12 s.

    (3 cm at the end: at 2 cm the derivative basis, its pairs weighted by the shake's
    amplification, follows the whole 9 s within 0.5 %.)
    """
    scene = variant('sheet_10x10', anchor_motion=[
        {'axis': 'x', 'amplitude': 0.02, 'frequency_hz': 0.7, 'ramp_s': 1.0},
        {'axis': 'z', 'amplitude': 0.03, 'frequency_hz': 9.5, 'ramp_s': 12.0}])
    path = tmp_path / 'ramped.yaml'
    path.write_text(scene_to_yaml(scene))
    return path


@pytest.mark.slow
def test_a_plan_the_run_outgrows_is_caught_by_its_watch_and_falls_back(tmp_path, capsys):
    """
    The pilot's window sees a gentle shake; the shake grows into large deformation later.

    Watched every 3 s, the plan measures 0.25 % from 3 s and is beyond 1 % from 6 s on: the run
    goes on as the full run from there, and a bag of it re-simulates through the fallback.
    """
    from modal_spring_ros.bags.files.reader import BagReader
    from modal_spring_ros.ros.tools.resimulate import resimulate
    bag = tmp_path / 'ramped'
    assert main(['--scene', str(ramped_shake(tmp_path)), '--auto', '--duration', '9',
                 '--watch', '3', '--frame-every', '40', '--bag', str(bag),
                 '--planning-share', 'none']) == 0      # the plan is measured, then watched
    out, err = capsys.readouterr()
    # each window on a line of its own, above the progress bar where one is shown
    lines = err.splitlines()
    within = [line for line in lines if line.startswith('[modal_spring_sim] watched')]
    told = out + err[-3000:]                                # what a failure shows
    assert len(within) == 2 and ' from t = 3 s against the full run' in within[0], told
    assert within[1].startswith("[modal_spring_sim] watched: a hair's difference"), told
    warning = [line for line in err.splitlines() if 'WARN: watched:' in line]
    assert len(warning) == 1 and 'beyond the tolerance 1.00%: the run falls back to the full' in (
        warning[0]), told
    error = float(warning[0].split('watched: ')[1].split('%')[0]) / 100
    start = float(warning[0].split('from t = ')[1].split(' s')[0])
    assert error > 0.01 and start == pytest.approx(6.0, abs=0.01)
    watched = [line for line in out.splitlines() if line.startswith('watched ')]
    # the full run fallen back to is watched by its twin (a window costs a twelfth of the 3 s
    # left), once, over the run's last quarter second
    assert len(watched) == 1, told
    fallen, then = watched[0].split(' watched then: ')
    assert fallen.endswith('beyond 1.00%: fell back to the full run,'), told
    assert then.startswith("1 window: last a hair's difference did not grow"), told
    assert then.endswith('over 0.25 s from t = 8.751 s'), told
    assert 'method     full physical (180 DOF)' in out
    again = tmp_path / 'again'
    resimulate(bag, again)
    t_rec, x_rec = BagReader(bag).points()
    t_new, x_new = BagReader(again).points()
    assert np.array_equal(t_new, t_rec)
    np.testing.assert_allclose(x_new, x_rec, rtol=0, atol=2e-6)


def test_a_run_longer_than_its_pilot_window_is_watched_at_least_once(capsys):
    """
    A run longer than one window is watched once, however long its interval.

    sheet_10x10 over 5 s (a 3 s window; watching every 10 s would cost more than a quarter of
    the plan, so its interval is far longer): one window, the run's last, from its own state.
    """
    assert main(['--auto', '--duration', '5', '--quiet', '--planning-share', 'none']) == 0
    out = capsys.readouterr().out
    watched = [line for line in out.splitlines() if line.startswith('watched ')]
    assert len(watched) == 1 and watched[0].startswith('watched    1 window: last ')
    start = float(watched[0].split('from t = ')[1].split(' s')[0])
    window = float(watched[0].split(' over ')[1].split(' s')[0])
    assert start > 1.0 and start + window == pytest.approx(5.0, abs=0.05)
    error = float(watched[0].split('last ')[1].split('%')[0]) / 100
    assert 0.0 < error <= 0.01


@pytest.mark.parametrize('duration, window', [(1.5, 0.15), (3.0, 0.25)])
def test_a_short_full_run_is_watched_once_by_its_twin_over_a_tenth_of_it(capsys, duration,
                                                                         window):
    """
    sheet_10x10 over 1.5 s and 3 s: the full run, its twin over its last tenth (a quarter second).

    A twin window costs the run the twin alone: within a tenth of the run, down to 0.1 s.
    """
    assert main(['--auto', '--duration', str(duration), '--quiet']) == 0
    out = capsys.readouterr().out
    assert 'method     full physical (180 DOF)' in out
    watched = [line for line in out.splitlines() if line.startswith('watched ')]
    assert len(watched) == 1, watched
    assert watched[0].startswith("watched    1 window: last a hair's difference did not grow")
    start = float(watched[0].split('from t = ')[1].split(' s')[0])
    span = float(watched[0].split(' over ')[1].split(' s')[0])
    assert span == pytest.approx(window, rel=0.05)
    assert start == pytest.approx(duration - window, abs=0.01)


def test_a_full_run_below_a_second_has_no_twin_window_and_says_why(capsys):
    """A tenth of the run is below 0.1 s: no window, and the summary's line says why."""
    assert main(['--auto', '--duration', '0.8', '--quiet']) == 0
    assert ('watched    no window: a window of its twin within 10% of the run would be shorter '
            'than 0.1 s') in capsys.readouterr().out


def test_running_out_of_memory_is_one_line_and_exit_2(capsys):
    """An allocation too large for the machine ends the command as any refusal does."""
    def body() -> int:
        raise MemoryError('Unable to allocate 22.4 GiB for an array with shape (3000000, 1000)')
    with pytest.raises(SystemExit) as ended:
        run_main('modal_spring_sim', body)
    assert ended.value.code == 2
    assert capsys.readouterr().err == ('modal_spring_sim: error: not enough memory: Unable to '
                                       'allocate 22.4 GiB for an array with shape '
                                       '(3000000, 1000)\n')


def test_an_amplifying_window_is_a_warning_that_keeps_the_run():
    calm = WatchedWindow(2.0, 0.25, 0.002, 0.01, 'the full run', growth=0.1)
    wild = WatchedWindow(2.0, 0.25, 0.002, 0.01, 'the full run', growth=9.0)
    assert not calm.amplifying and watched_line(calm, None).startswith('watched: 0.20% ')
    assert wild.amplifying and wild.within           # its error met: not fallen back
    line = watched_line(wild, None)
    assert line.startswith('WARN: watched: 0.20% ') and 'e-fold every 0.11 s' in line
    assert line.endswith(UNBOUNDED)


def test_a_run_keeping_no_frame_goes_on_from_where_the_pilot_s_run_of_it_ended(tmp_path, capsys):
    # a scene with colliders has the chosen step checked over the pilot's whole window: the
    # run at that step was stepped from rest that far, and is not stepped again
    scene = tmp_path / 'table.yaml'
    scene.write_text(scene_to_yaml(sheet_on_a_table()))
    args = ['--scene', str(scene), '--auto', '--duration', '1.5', '--quiet']
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "where the pilot's run of it ended: not stepped again" in out, out
    assert main(args + ['--output', str(tmp_path / 'kept.npz')]) == 0
    kept = capsys.readouterr().out
    assert 'not stepped again' not in kept             # its frames from t = 0 are kept
    # where it goes on from is where stepping from rest gets to
    sim = build_simulation(load_scene(scene), SimulationConfig(auto=True, horizon_s=1.5))
    assert head_start(sim, 1.5, keeps_frames=True) == 0.0 and sim.time == 0.0
    ahead = head_start(sim, 1.5, keeps_frames=False)
    assert 0.0 < ahead <= 1.5
    again = sim.with_dt(sim.dt)
    again.step(round(ahead / sim.dt))
    size = np.abs(again.displacement()).max()
    assert np.abs(sim.displacement() - again.displacement()).max() <= 1e-9 * size
    ended = record(sim, 1.5 - ahead, keep_frames=False)
    stepped = np.load(tmp_path / 'kept.npz')['positions'][-1]
    assert np.abs(ended.positions[-1] - stepped).max() <= 1e-9 * np.abs(stepped).max()

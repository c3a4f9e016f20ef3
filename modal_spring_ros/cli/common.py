"""What the console scripts share: simulation options on argparse, and clean error exits."""
from __future__ import annotations

import argparse
import contextlib
import dataclasses
import os
from pathlib import Path
import re
import sys
import time
from typing import Callable, Iterator, NoReturn
import weakref

from modal_spring_ros.core.auto.budget import PLANNING_SHARE
from modal_spring_ros.core.config import DEFAULT_WATCH_S, SimulationConfig
from modal_spring_ros.core.filter_band import BandError, FILTER_TYPES, FilterBand
from modal_spring_ros.core.filter_response import ACTS_ON
from modal_spring_ros.core.forces import FORCES
from modal_spring_ros.core.integrators import INTEGRATORS
from modal_spring_ros.core.model.scene import SceneError
from modal_spring_ros.core.simulations import DEFAULT_MAX_MODES, METHODS
from modal_spring_ros.core.simulations.coordinates import BASES
from modal_spring_ros.core.threads import process_threads
from modal_spring_ros.scenes.resources import DEFAULT_SCENE
from tqdm import tqdm

#: Exit status for bad input (as argparse uses).
EXIT_USAGE = 2
#: Bytes written (and taken back) to check that an output file has room.
PROBE_BYTES = 4096
#: Long work shows a progress bar once it has taken this long, s (a short run shows none).
PROGRESS_DELAY_S = 1.0
#: The progress bars open (a line printed beside them is printed above one shown).
_BARS: 'weakref.WeakSet[tqdm]' = weakref.WeakSet()

#: the core's defaults, which the options take (one place for each)
DEFAULTS = SimulationConfig()


def script_parser(prog: str, doc: str) -> argparse.ArgumentParser:
    """Return the parser of a console script whose module text starts ``prog: what it does.``."""
    summary = doc.strip().splitlines()[0]
    return argparse.ArgumentParser(prog=prog, description=summary.split(': ', 1)[1])


def split_ros_args(argv: list[str] | None) -> tuple[list[str], list[str]]:
    """Split the tool's own arguments from ``--ros-args ...`` (for rclpy), as ROS tools do."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if '--ros-args' in argv:
        k = argv.index('--ros-args')
        return argv[:k], argv[k:]
    return argv, []


def claim_output_file(path: str, option: str, others: dict[str, str | None] | None = None
                      ) -> bool:
    """
    Fail before long work, not after it, when an output file cannot be written.

    Create it now (an unwritable folder, a name too long, a full device fail here), and refuse one
    that is the same file as another path of the command (``others``: name -> path, an input or
    another output). Returns whether the file was created here (an existing one is left as it is
    until it is written).

    Raises ValueError naming ``option``.
    """
    try:
        return _claim(Path(path), path, option, others or {})
    except OSError as exc:  # a name the file system refuses even to look up
        raise ValueError(f'{option} {path}: cannot write: {exc.strerror or exc}') from None


def _claim(target: Path, path: str, option: str, others: dict[str, str | None]) -> bool:
    for name, other in others.items():
        if other and (os.path.abspath(other) == os.path.abspath(target) or (
                target.exists() and Path(other).exists() and os.path.samefile(other, target))):
            raise ValueError(f'{option} {path}: is also {name}; choose another file '
                             '(nothing was overwritten)')
    if target.is_dir():
        raise ValueError(f'{option} {path}: is a folder, not a file')
    folder = target.parent if str(target.parent) else Path('.')
    if not folder.is_dir():
        raise ValueError(f'{option} {path}: folder {folder} does not exist')
    existed = target.exists()
    try:
        with open(target, 'ab') as fh:
            if not existed:  # room for at least a block: a full device fails now
                fh.write(bytes(PROBE_BYTES))
                fh.flush()
                os.fsync(fh.fileno())
                fh.truncate(0)
    except OSError as exc:
        if not existed:
            with contextlib.suppress(OSError):
                target.unlink()
        raise ValueError(f'{option} {path}: cannot write: {exc.strerror or exc}') from None
    return not existed


@contextlib.contextmanager
def claimed_outputs(outputs: dict[str, str | None],
                    others: dict[str, str | None] | None = None) -> Iterator[None]:
    """
    Claim every output (option -> path, None when not asked for) before the work.

    If the work fails, the files created here are removed again: bad input changes nothing.
    """
    others = others or {}
    created = [path for option, path in outputs.items()
               if path and claim_output_file(path, option,
                                             {k: v for k, v in others.items() if k != option})]
    try:
        yield
    except BaseException:
        for path in created:
            with contextlib.suppress(OSError):
                if os.path.getsize(path) == 0:
                    os.remove(path)
        raise


def write_output(path: str, option: str, write: Callable[[], None]) -> None:
    """
    Run ``write`` (which writes ``path``); a failure is one line naming ``option``.

    A regular file the failure left half-written (a full disk) is removed: no truncated output
    stays. Anything else (a device such as /dev/full, a FIFO, a link) is never removed.
    """
    try:
        write()
    except OSError as exc:
        if os.path.isfile(path) and not os.path.islink(path):
            with contextlib.suppress(OSError):
                os.remove(path)
        raise ValueError(f'{option} {path}: cannot write: {exc.strerror or exc}') from None


def fail(prog: str, message: str, status: int = EXIT_USAGE) -> NoReturn:
    print(f'{prog}: error: {message}', file=sys.stderr)
    raise SystemExit(status)


def add_simulation_options(parser: argparse.ArgumentParser) -> None:
    g = parser.add_argument_group('simulation')
    g.add_argument('--scene', default=DEFAULT_SCENE,
                   help=f'built-in scene name or YAML path (default {DEFAULT_SCENE})')
    g.add_argument('--method', choices=METHODS, default=DEFAULTS.method)
    g.add_argument('--filter', dest='filter_type', choices=FILTER_TYPES, default=None,
                   help='filter band type (default allpass)')
    g.add_argument('--low-hz', type=float, default=None, help='lower band edge, Hz')
    g.add_argument('--high-hz', type=float, default=None, help='upper band edge, Hz')
    g.add_argument('--modes', default=None, metavar='FIRST:LAST',
                   help='keep modes FIRST..LAST (zero-based, inclusive) instead of a Hz band;'
                        ' with --filter bandstop, drop them')
    g.add_argument('--order', type=int, default=0, metavar='N',
                   help='Butterworth roll-off of order N at the band edges (-3 dB at each '
                        'edge; default 0: ideal edges, keep or drop)')
    g.add_argument('--gain', action='append', default=[], metavar='TERM',
                   help='a gain in dB (repeatable): LOW_HZ:HIGH_HZ:DB over a range, '
                        'peak:CENTER:WIDTH:DB, low_shelf:CORNER:DB or high_shelf:CORNER:DB')
    g.add_argument('--gains-act-on', choices=ACTS_ON, default='output',
                   help='output: the gains colour the positions (the motion stays physical; '
                        'default); load: they scale the loads driving each mode')
    g.add_argument('--damping-ratio', action='append', default=[], metavar='LOW:HIGH:RATIO',
                   help='modes within LOW..HIGH Hz damped with modal ratio RATIO instead of '
                        "the scene's (repeatable)")
    g.add_argument('--integrator', choices=INTEGRATORS, default=DEFAULTS.integrator)
    g.add_argument('--dt', type=float, default=None,
                   help="time step, s (default: the scene's, else half the stability limit)")
    g.add_argument('--transition-s', type=float, default=DEFAULTS.transition_s,
                   help=f'fade time of modes leaving the band, s (default '
                        f'{DEFAULTS.transition_s:g})')
    g.add_argument('--max-modes', type=int, default=None,
                   help=f'most modes computed on large scenes (default {DEFAULT_MAX_MODES})')
    g.add_argument('--auto', action='store_true',
                   help='keep the fewest modes (within the band) that meet --tolerance for the '
                        "scene's loads, the step they allow (unless --dt), and the basis "
                        '(in place of --basis)')
    g.add_argument('--tolerance', type=float, default=DEFAULTS.tolerance,
                   help='relative error --auto holds over --duration, measured (default '
                        f'{DEFAULTS.tolerance:g})')
    g.add_argument('--planning-share', type=share_or_none, default=PLANNING_SHARE,
                   metavar='SHARE',
                   help='with --auto: the most its planning may spend, as a share of the full '
                        'run over --duration (a pilot that would cost more, or more than the '
                        f'plan could save, is not run: the full run is; default '
                        f'{PLANNING_SHARE:g}; none: not budgeted)')
    g.add_argument('--watch', type=float, default=None, metavar='SECONDS',
                   help="with --auto: measure the plan's error again from the run's own state "
                        'every SECONDS of the run, and fall back to the full run (or a richer '
                        'plan) where it is beyond --tolerance; 0: not watched (default: every '
                        f'{DEFAULT_WATCH_S:g} s, or less often where watching would cost more '
                        'than a quarter of the run)')
    g.add_argument('--basis', choices=BASES, default=DEFAULTS.basis,
                   help="modal coordinates: the band's rest modes (the paper's method), or "
                        'those plus their modal derivatives and static load vectors (right '
                        'beyond small deformation; default)')
    g.add_argument('--derivative-directions', type=int, default=DEFAULTS.derivative_directions,
                   metavar='N', help='modal-derivative directions a band adds '
                                     f'(default {DEFAULTS.derivative_directions})')
    g.add_argument('--forces', choices=tuple(FORCES), default=DEFAULTS.forces,
                   help='spring forces: exact (every spring, every step: the paper), '
                        'refreshed (every --force-refresh steps, a tangent between) or '
                        'sampled (a weighted sample of the springs within --tolerance, '
                        'trained once and cached); --auto chooses in its place')
    g.add_argument('--force-refresh', type=int, default=DEFAULTS.force_refresh, metavar='N',
                   help='evaluate the nonlinear spring forces every N steps and continue '
                        'them along the static tangent in between (default: every step, '
                        'or what --auto chooses)')


#: configuration field -> option, so that configuration errors name the option
OPTION_NAMES = {'method': '--method', 'auto': '--auto', 'integrator': '--integrator', 'dt': '--dt',
                'transition_s': '--transition-s', 'max_modes': '--max-modes',
                'strain_limit': '--strain-limit', 'tolerance': '--tolerance',
                'force_refresh': '--force-refresh', 'basis': '--basis',
                'derivative_directions': '--derivative-directions', 'forces': '--forces',
                'horizon_s': '--duration', 'watch_s': '--watch',
                'planning_share': '--planning-share', 'type': '--filter',
                'low_hz': '--low-hz', 'high_hz': '--high-hz', 'order': '--order',
                'gains': '--gain',
                'acts_on': '--gains-act-on', 'damping': '--damping-ratio'}
#: the edges of ``--modes FIRST:LAST``
MODES_NAMES = {'low_mode': 'FIRST', 'high_mode': 'LAST'}


def parse_mode_range(text: str) -> FilterBand:
    """``"FIRST:LAST"`` (inclusive, zero-based) as an index band-pass, e.g. ``"0:14"``."""
    parts = text.split(':')
    if len(parts) != 2:
        raise BandError(f"--modes '{text}' must be FIRST:LAST, e.g. 0:14")
    try:
        first = int(parts[0]) if parts[0] else 0
        last = int(parts[1])
    except ValueError:
        raise BandError(f"--modes '{text}' must be two whole numbers FIRST:LAST") from None
    if first < 0 or last < first:
        raise BandError(f"--modes '{text}': need 0 <= FIRST <= LAST")
    kind = 'lowpass' if first == 0 else 'bandpass'
    return FilterBand(kind, float(first), float(last), 'index').validate(MODES_NAMES)


def band_from_args(args: argparse.Namespace) -> FilterBand:
    """Return the filter (band and shape) the options describe; BandError names the option."""
    band = _edges_from_args(args)
    if args.order and band.by == 'index':
        raise BandError('--order rounds edges in Hz: give the band with --low-hz/--high-hz, '
                        'not --modes')
    return dataclasses.replace(band, order=args.order, gains=tuple(args.gain),
                               acts_on=args.gains_act_on,
                               damping=tuple(args.damping_ratio)).validate(OPTION_NAMES)


def _edges_from_args(args: argparse.Namespace) -> FilterBand:
    kind = args.filter_type or ('bandpass' if args.modes else 'allpass')
    if args.modes is not None:
        if args.low_hz is not None or args.high_hz is not None:
            raise BandError('--modes and --low-hz/--high-hz exclude each other')
        band = parse_mode_range(args.modes)
        if kind == 'bandstop':
            return FilterBand('bandstop', band.low, band.high, 'index').validate(MODES_NAMES)
        if kind not in ('bandpass', 'lowpass'):
            raise BandError(f'--modes keeps a range of modes: use it with --filter bandpass '
                            f'or bandstop, not {kind}')
        return band
    if kind != 'allpass':
        needs_low = kind in ('highpass', 'bandpass', 'bandstop')
        needs_high = kind in ('lowpass', 'bandpass', 'bandstop')
        if needs_low and args.low_hz is None:
            raise BandError(f'--filter {kind} needs --low-hz')
        if needs_high and args.high_hz is None:
            raise BandError(f'--filter {kind} needs --high-hz')
    low = args.low_hz if args.low_hz is not None else 0.0
    high = args.high_hz if args.high_hz is not None else float('inf')
    return FilterBand(kind, low, high, 'hz').validate(OPTION_NAMES)


def config_from_args(args: argparse.Namespace) -> SimulationConfig:
    """Return the run the options describe, validated (errors name the option)."""
    return SimulationConfig(method=args.method, band=band_from_args(args),
                            integrator=args.integrator, dt=args.dt,
                            transition_s=args.transition_s, max_modes=args.max_modes,
                            auto=args.auto, tolerance=args.tolerance,
                            force_refresh=args.force_refresh, basis=args.basis,
                            derivative_directions=args.derivative_directions,
                            forces=args.forces, watch_s=args.watch,
                            planning_share=args.planning_share).validate(OPTION_NAMES)


def share_or_none(text: str) -> float | None:
    """Parse ``--planning-share``: a number, or ``none``."""
    if text.strip().lower() == 'none':
        return None
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a share (a number) or none") from None


def run_main(prog: str, body: Callable[[], int]) -> int:
    """
    Run a command body, turning known errors into one clear line and exit status 2.

    On one BLAS thread unless the environment names a count (:func:`~modal_spring_ros.core.
    threads.process_threads`: a user pays the CPU of a run's one-off work too).
    """
    try:
        with process_threads(os.environ):
            return body()
    except (SceneError, BandError, ValueError) as exc:
        fail(prog, str(exc))
    except MemoryError as exc:   # numpy names the array it could not allocate
        fail(prog, f'not enough memory: {exc or "an allocation failed"}')
    except KeyboardInterrupt:
        return 130


def progress_bar(prog: str, total: float, unit: str, what: str, quiet: bool = False,
                 delay_s: float = PROGRESS_DELAY_S) -> Callable[..., None]:
    """
    Return ``show(done, final=False)``: a progress bar on stderr, its rate and time left (tqdm).

    ``total`` of ``unit`` (``what`` names the work); shown only once the work has taken
    ``delay_s`` (a short run shows none), and closed when ``done`` reaches ``total`` or is
    ``final`` (work that ended early: a divergence). ``quiet``: nothing is shown.
    """
    if quiet:
        return lambda done, final=False: None
    bar = tqdm(total=total, unit=unit, desc=f'[{prog}] {what}', file=sys.stderr,
               delay=delay_s, leave=True, dynamic_ncols=True,
               bar_format='{desc}: {percentage:3.0f}%|{bar}| {n:.4g}/{total:.4g} {unit} '
                          '[{elapsed}<{remaining}]')
    _BARS.add(bar)

    def show(done: float, final: bool = False) -> None:
        if bar.disable:
            return
        bar.update(min(done, total) - bar.n)
        if final or done >= total:
            bar.close()
    return show


def beside_bar(prog: str, line: str) -> None:
    """
    Print ``line`` on stderr on a line of its own, above a progress bar shown (tqdm's).

    Where no bar is shown yet (a short run's waits for its delay), a plain line: tqdm's write
    would show a waiting bar, which its close then leaves without its end of line.
    """
    if any(not bar.disable and bar.last_print_t >= bar.start_t + bar.delay for bar in _BARS):
        tqdm.write(f'[{prog}] {line}', file=sys.stderr)
    else:
        print(f'[{prog}] {line}', file=sys.stderr, flush=True)


#: a benchmark's count of its jobs at the start of a progress line: ``promise 41/100: ...``
COUNTED = re.compile(r'^(\w+) (\d+)/(\d+):')


def progress_lines(prog: str, clock: Callable[[], float] = time.monotonic
                   ) -> Callable[[str], None]:
    """
    Return ``say(line)``: progress lines on stderr, a counted one with the time it has left.

    A line that counts its jobs (``promise 41/100: ...``) gets the time the rest is estimated
    to take at the pace of the jobs counted so far (from its first counted line on).
    """
    first: dict[str, tuple[float, int]] = {}

    def say(line: str) -> None:
        counted = COUNTED.match(line)
        if counted:
            name, done, total = counted[1], int(counted[2]), int(counted[3])
            since, done_then = first.setdefault(name, (clock(), done))
            if done > done_then and done < total:
                left = (clock() - since) / (done - done_then) * (total - done)
                line += f' (about {_duration(left)} left)'
        print(f'[{prog}] {line}', file=sys.stderr, flush=True)
    return say


def _duration(seconds: float) -> str:
    """Return ``seconds`` as people say it: 40 s, 3 min, 1 h 20 min."""
    if seconds < 90:
        return f'{seconds:.0f} s'
    if seconds < 90 * 60:
        return f'{seconds / 60:.0f} min'
    return f'{int(seconds // 3600)} h {int(seconds % 3600 // 60)} min'

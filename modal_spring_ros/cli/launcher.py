"""
Where every console script starts: the script's module is imported here, under Ctrl-C's guard.

A console script's wrapper imports its entry point before it calls it, so an interrupt during
the first second of imports (numpy, scipy, rclpy) would end in a traceback from the import
itself. Each function here imports its script's module (``modal_spring_ros.cli.<name>``, the
one place this package imports lazily: the import is what is guarded) and runs its ``main``;
an interrupt before ``main`` has installed its own handling ends quietly with status 130, as
a shell reports a Ctrl-C.

The interrupt is also remembered: Python raises ``KeyboardInterrupt`` wherever the interpreter
happens to be, and code that swallows every exception there (an extension's initialisation, a
library's ``except BaseException``) would lose it, and the node would start streaming after
the user pressed Ctrl-C. A remembered interrupt ends the run before ``main``. Where SIGINT is
ignored (a shell's background job), it stays ignored, as for any program.

The working directory is taken off the import path first (:func:`safe_path`): nothing in a
folder of data is imported.

A crash in native code (the middleware, a BLAS) prints every thread's Python stack on stderr
(:mod:`faulthandler`) before the process ends, so a report says where it happened.
"""
from __future__ import annotations

import faulthandler
import functools
import importlib
import os
import signal
import sys
from typing import Any, Callable

#: Exit status of a run ended by Ctrl-C before it started (128 + SIGINT), as a shell reports it.
EXIT_INTERRUPTED = 130

#: Exit status of a script whose packages are not installed (as argparse's usage errors).
EXIT_MISSING = 2
#: The optional extras (``pip install '.[extra]'``) that bring a missing top-level module;
#: every other missing module is one of ROS's (the ``ros`` extra, or a ROS install).
EXTRA_OF = {'foxglove': 'view'}

#: The console scripts, each a module of this package named after it.
SCRIPTS = ('modal_spring_sim', 'modal_spring_node', 'modal_spring_bench', 'modal_spring_replay',
           'modal_spring_compare', 'modal_spring_record', 'modal_spring_gripper',
           'modal_spring_render', 'modal_spring_view', 'modal_spring_reindex')


def run(script: str) -> int:
    """Import the module of console script ``script`` and run its ``main``."""
    safe_path()
    return run_module(f'{__package__}.{script}')


def safe_path() -> None:
    """
    Take the working directory off the import path, as ``python -P`` does.

    A tool is run from folders of data (a downloaded bag, a scene's folder); a ``.py`` file
    there must never be imported in place of a package. A ``PYTHONPATH`` with an empty entry
    (a trailing ``:``, common in sourced setups) or a relative one (``.``) would otherwise put
    it there: every entry that is not an absolute path is dropped.
    """
    sys.path[:] = [p for p in sys.path if os.path.isabs(p)]


def install_hint(missing: str) -> str:
    """Say how to install the optional package that brings module ``missing``."""
    extra = EXTRA_OF.get(missing.split('.')[0], 'ros')
    return (f"pip install '.[{extra}]'" if extra != 'ros' else
            "pip install '.[ros]' (ROS 2 Jazzy from PyPI wheels), or source a ROS 2 install")


def run_module(name: str) -> int:
    """
    Import module ``name`` under Ctrl-C's guard and run its ``main``.

    A module that needs a package not installed (``pip install .`` brings no ROS) ends in one
    line that names it and says how to install it, not in a traceback.
    """
    faulthandler.enable(all_threads=True)
    interrupts = _remember_interrupts()
    try:
        hook = sys.unraisablehook
        sys.unraisablehook = functools.partial(_unless_interrupt, hook)
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            script = name.rsplit('.', 1)[-1]
            print(f'{script}: needs {exc.name}, which is not installed: '
                  f'{install_hint(exc.name or "")}', file=sys.stderr)
            return EXIT_MISSING
        finally:
            sys.unraisablehook = hook
        if interrupts:                  # pressed during the imports, and swallowed there
            return EXIT_INTERRUPTED
        return module.main()
    except KeyboardInterrupt:
        return EXIT_INTERRUPTED
    except Exception as exc:
        if _interrupted(exc):
            return EXIT_INTERRUPTED
        raise


def _unless_interrupt(report: Callable[[Any], None], unraisable: Any) -> None:
    """
    Report an exception Python could not raise, unless it is an interrupt.

    A Ctrl-C that lands in a callback of the import system (its module locks' weak references)
    cannot propagate: Python reports it as "Exception ignored", with a traceback. During the
    imports every interrupt is remembered and answered by the exit status, so it is not reported.
    """
    if not isinstance(unraisable.exc_value, KeyboardInterrupt):
        report(unraisable)


def _remember_interrupts() -> list[int]:
    """
    Handle SIGINT as Python does (``KeyboardInterrupt``), and remember each one.

    Only where SIGINT has Python's own handler (a shell's background job ignores it: kept so).
    """
    seen: list[int] = []
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:

        def remember(signum, frame):
            seen.append(signum)
            raise KeyboardInterrupt
        signal.signal(signal.SIGINT, remember)
    return seen


def _interrupted(exc: BaseException) -> bool:
    """
    Tell an interrupt that an import wrapped in another exception.

    Python 3.11 reports a KeyboardInterrupt raised while a class is created (in
    ``__set_name__``, say of a ``cached_property``) as a RuntimeError caused by it.
    """
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


# The console scripts' entry points (setup.py names them): each runs its own module's main.
modal_spring_sim = functools.partial(run, 'modal_spring_sim')
modal_spring_node = functools.partial(run, 'modal_spring_node')
modal_spring_bench = functools.partial(run, 'modal_spring_bench')
modal_spring_replay = functools.partial(run, 'modal_spring_replay')
modal_spring_compare = functools.partial(run, 'modal_spring_compare')
modal_spring_record = functools.partial(run, 'modal_spring_record')
modal_spring_gripper = functools.partial(run, 'modal_spring_gripper')
modal_spring_render = functools.partial(run, 'modal_spring_render')
modal_spring_view = functools.partial(run, 'modal_spring_view')
modal_spring_reindex = functools.partial(run, 'modal_spring_reindex')

"""
The linters a ROS 2 Python package runs as tests: ament_flake8 and ament_pep257.

As ``ros2 pkg create`` sets them up (markers ``linter``, ``flake8``, ``pep257``; the tools' own
configuration), over the package, its tests and ``setup.py``. Each also runs on a file with known
findings: ament_flake8 without its plugins (quotes, import order, docstrings) finds nothing at all,
and that must not pass for clean code.
"""
from __future__ import annotations

import contextlib
import io

from ament_flake8.main import main_with_errors as flake8_main
from ament_pep257.main import main as pep257_main
from helpers import REPO
import pytest

CHECKED = [str(REPO / 'modal_spring_ros'), str(REPO / 'test'), str(REPO / 'setup.py')]

BAD = '''def f(x):
    """returns x"""
    import sys, os
    return dict(a="b")
'''


def _pep257(paths: list[str]) -> tuple[int, str]:
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
        rc = pep257_main(argv=paths)
    return rc, out.getvalue()


@pytest.mark.flake8
@pytest.mark.linter
@pytest.mark.slow
def test_flake8():
    rc, errors = flake8_main(argv=CHECKED)
    assert rc == 0, f'Found {len(errors)} code style errors / warnings:\n' + '\n'.join(errors)


@pytest.mark.linter
@pytest.mark.pep257
def test_pep257():
    rc, report = _pep257(CHECKED)
    findings = '\n'.join(line for line in report.splitlines() if not line.startswith('checking'))
    assert rc == 0, f'Found code style errors / warnings:\n{findings}'


@pytest.mark.linter
def test_the_linters_find_what_they_are_for(tmp_path):
    bad = tmp_path / 'bad.py'
    bad.write_text(BAD)
    rc, errors = flake8_main(argv=[str(bad)])
    codes = {e.split(': ')[1].split()[0] for e in errors if ': ' in e}
    # quotes, one import per line, dict literal, docstring form: every plugin is installed
    assert rc != 0 and {'Q000', 'E401', 'C408', 'D400', 'D403'} <= codes, errors
    rc, report = _pep257([str(bad)])
    assert rc != 0 and 'D400' in report and 'D401' in report, report

"""
The README's two commands: what each bootstraps, and that CI runs the second one exactly.

The node's command builds only what the node needs (``.ci/bootstrap``); the tests' command adds
the test tools and the venv without ROS (``.ci/bootstrap test``). Once built, either is a no-op.
"""
from __future__ import annotations

from pathlib import Path
import re
import subprocess

import pytest

REPO = Path(__file__).resolve().parents[2]
BOOTSTRAP = REPO / '.ci' / 'bootstrap'

pytestmark = pytest.mark.skipif(not BOOTSTRAP.exists(),
                                reason='not in the source tree (a colcon workspace copy)')


def readme_commands() -> list[str]:
    first_block = re.search(r'```bash\n(.*?)```', (REPO / 'README.md').read_text(), re.S)
    return first_block.group(1).strip().splitlines()


def test_the_readme_starts_with_two_commands_and_ci_runs_the_second():
    node, tests = readme_commands()
    assert node == '.ci/bootstrap && .venv/bin/modal_spring_node'
    assert tests == '.ci/bootstrap test && .venv/bin/python -m pytest -q -n 2 --dist loadgroup'
    run = (REPO / '.ci' / 'run').read_text().splitlines()
    assert tests in run


def built() -> bool:
    """Tell whether ``.ci/bootstrap test`` built the venvs from these very scripts."""
    return subprocess.run([str(BOOTSTRAP), 'check'], capture_output=True,
                          timeout=60).returncode == 0


@pytest.mark.slow
def test_both_bootstraps_are_no_ops_once_built_and_a_wrong_target_is_refused():
    if not built():
        pytest.skip('the venvs were not built by .ci/bootstrap test from these scripts')
    for args in ([], ['test']):       # built by the command that runs these tests: nothing to do
        done = subprocess.run([str(BOOTSTRAP), *args], capture_output=True, text=True,
                              timeout=60)
        assert (done.returncode, done.stderr) == (0, ''), done.stderr
    wrong = subprocess.run([str(BOOTSTRAP), 'everything'], capture_output=True, text=True,
                           timeout=60)
    assert wrong.returncode == 2 and 'usage: .ci/bootstrap [node|test|check]' in wrong.stderr

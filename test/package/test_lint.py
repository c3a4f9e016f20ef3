"""The code follows the project's style: flake8 (pycodestyle and pyflakes) with the settings in
``setup.cfg``, over the package, its tests and ``setup.py``."""
from __future__ import annotations

import subprocess
import sys

from helpers import REPO


def test_flake8_finds_nothing():
    proc = subprocess.run([sys.executable, "-m", "flake8", "modal_spring_ros", "test",
                           "setup.py"], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, f"flake8 findings:\n{proc.stdout}{proc.stderr}"

"""
Where an installed ROS package's folders are: the ament index, with or without ROS.

On a ROS install or in a colcon workspace ``ament_index_python`` answers. A pip install without
the ROS extra has no ``ament_index_python``, and the PyPI wheels set no ``AMENT_PREFIX_PATH``;
the index is only a folder convention (a package is installed under a prefix that holds
``share/ament_index/resource_index/packages/<name>``), so where ``ament_index_python`` is missing
or does not know the package, the same lookup is made over ``AMENT_PREFIX_PATH`` and this
interpreter's prefix.
"""
from __future__ import annotations

import os
from pathlib import Path
import sys

try:
    from ament_index_python.packages import get_package_prefix, PackageNotFoundError
except ImportError:      # a pip install without ROS: the same lookup, below
    get_package_prefix, PackageNotFoundError = None, LookupError

MARKERS = Path('share') / 'ament_index' / 'resource_index' / 'packages'


def package_prefix(name: str) -> Path | None:
    """Return the prefix ``name`` is installed under, or None when it is not in the index."""
    if get_package_prefix is not None:
        try:
            return Path(get_package_prefix(name))
        except (PackageNotFoundError, LookupError, ValueError, OSError):  # OSError: no index
            pass        # the PyPI wheels set no AMENT_PREFIX_PATH: their index is sys.prefix's
    prefixes = [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    for prefix in [*prefixes, sys.prefix]:
        if (Path(prefix) / MARKERS / name).is_file():
            return Path(prefix)
    return None


def package_share(name: str) -> Path | None:
    """Return ``name``'s share folder, or None when it is not in the index."""
    prefix = package_prefix(name)
    return None if prefix is None else prefix / 'share' / name

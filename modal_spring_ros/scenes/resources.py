"""
Where the package's data lives, and the built-in scenes: names, lookup, loading.

The package's data folder is the repository itself in a source checkout or editable install,
``<prefix>/share/modal_spring_ros`` when installed (found through the ament index on a ROS
install, else under the Python prefix of a pip install).
"""
from __future__ import annotations

from pathlib import Path
import sys
from typing import Callable

from modal_spring_ros.core.model.scene import Scene, SceneError
from modal_spring_ros.scenes.ament_index import package_prefix, package_share
from modal_spring_ros.scenes.files.yaml_reading import read_scene_text
from modal_spring_ros.scenes.schema import scene_from_yaml

PACKAGE_NAME = 'modal_spring_ros'


def share_directory() -> Path:
    """
    Return the package's data folder (``config/`` lives there).

    A source checkout or editable install uses the repository itself; an installed package uses
    ``<prefix>/share/modal_spring_ros`` (found with ament_index on a ROS install, or under the
    Python prefix for a pip install into a venv).
    """
    source = Path(__file__).resolve().parents[2]  # the repository, in a source checkout
    if (source / 'config' / 'scenes').is_dir():
        return source
    share = package_share(PACKAGE_NAME)
    return share if share is not None else Path(sys.prefix) / 'share' / PACKAGE_NAME


def executable(name: str) -> Path:
    """
    Return the path of the package's console script ``name``.

    Found as ``ros2 run`` finds it, ``<prefix>/lib/modal_spring_ros/<name>`` with the prefix from
    the ament index (a colcon workspace or a ROS install), else beside this interpreter (a venv).

    :raises FileNotFoundError: the script is in neither place.
    """
    prefix = package_prefix(PACKAGE_NAME)
    places = [] if prefix is None else [prefix / 'lib' / PACKAGE_NAME / name]
    places.append(Path(sys.executable).parent / name)
    for path in places:
        if path.is_file():
            return path
    raise FileNotFoundError(f"{name} is not installed (looked in {', '.join(map(str, places))})")


def builtin_scene_dir() -> Path:
    """Folder holding the built-in scene files."""
    return share_directory() / 'config' / 'scenes'


#: The scene used when none is named.
DEFAULT_SCENE = 'sheet_10x10'


def builtin_scene_names() -> list[str]:
    """Names of the scenes shipped with the package."""
    return sorted(p.stem for p in builtin_scene_dir().glob('*.yaml'))


def scene_file(name_or_path: str | Path) -> Path:
    """
    Return the file of a scene path, or of a built-in scene's name.

    :raises SceneError: a name that is neither a file nor a built-in scene.
    """
    text = str(name_or_path)
    path = Path(text)
    if text.endswith(('.yaml', '.yml')) or path.exists():
        return path
    candidate = builtin_scene_dir() / f'{text}.yaml'
    if not candidate.exists():
        raise SceneError(f"unknown scene '{text}': not a file, and not a built-in scene "
                         f"(built-in: {', '.join(builtin_scene_names())})")
    return candidate


def load_scene(name_or_path: str | Path,
               progress: Callable[[str], None] | None = None) -> Scene:
    """
    Load a built-in scene by name, or a scene file by path (``progress`` hears of long work).

    :raises SceneError: unknown name, unreadable file, invalid YAML or an invalid scene.
    """
    path = scene_file(name_or_path)
    return scene_from_yaml(read_scene_text(path), source=str(path), default_name=path.stem,
                           progress=progress)

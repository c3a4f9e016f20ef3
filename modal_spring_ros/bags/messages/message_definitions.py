"""
Message definitions as rosbag2 stores them in MCAP schemas, and ROS 2 type hashes.

rosbag2 (``LocalMessageDefinitionSource``) stores a type's full definition as its ``.msg``
text followed, for each dependency (sorted by name, depth first, each once), by a newline, a
line of 80 ``=``, a line ``MSG: pkg/Type`` and that type's ``.msg`` text. Dependencies are the
field types found at the start of lines; a type without a package takes the package of the
file it appears in. The ``.msg`` files come from the installed packages' ``share`` folders.
"""
from __future__ import annotations

import functools
import json
from pathlib import Path
import re
import sys

from modal_spring_ros.bags.messages.message_types import split_type_name, TypeRefused
from modal_spring_ros.scenes.ament_index import package_share

DELIMITER = '=' * 80 + '\n'
_FIELD_TYPE = re.compile(r'(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+')
_PRIMITIVES = {'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16',
               'int32', 'uint32', 'int64', 'uint64', 'string'}


class DefinitionNotFound(LookupError):
    """No installed ``.msg`` file for a type."""


def share_directory(package: str) -> Path:
    """``share/<package>``: from the ament index when there is one, else the Python prefix."""
    share = package_share(package)
    return share if share is not None else Path(sys.prefix) / 'share' / package


@functools.lru_cache(maxsize=None)
def msg_text(type_name: str) -> str:
    try:
        package, kind, name = split_type_name(type_name)
    except TypeRefused as exc:
        raise DefinitionNotFound(str(exc)) from None
    path = share_directory(package) / kind / f'{name}.msg'
    try:
        return path.read_text(encoding='utf-8')
    except OSError:
        raise DefinitionNotFound(f'no message definition for {type_name} ({path})') from None


def dependencies(text: str, package: str) -> list[str]:
    deps = set()
    for match in _FIELD_TYPE.finditer(text):
        t = match.group(1)
        if t in _PRIMITIVES:
            continue
        deps.add(t if '/' in t else f'{package}/{t}')
    return sorted(deps)


def full_definition(type_name: str) -> str:
    """Return the ``ros2msg`` schema text rosbag2 writes for ``type_name`` (pkg/msg/Type)."""
    seen: set[str] = set()

    def expand(name: str) -> str:
        text = msg_text(name)
        out = text
        for dep in dependencies(text, split_type_name(name)[0]):
            if dep not in seen:
                seen.add(dep)
                out += '\n' + DELIMITER + f'MSG: {dep}\n' + expand(dep)
        return out

    return expand(type_name)


@functools.lru_cache(maxsize=None)
def type_hash(type_name: str) -> str:
    """Return the RIHS01 type description hash of ``type_name`` (empty when unknown)."""
    try:
        package, kind, name = split_type_name(type_name)
    except TypeRefused:
        return ''
    path = share_directory(package) / kind / f'{name}.json'
    try:
        data = json.loads(path.read_text(encoding='utf-8'))
    except (OSError, ValueError):
        return ''
    full = f'{package}/{kind}/{name}'
    for entry in data.get('type_hashes', []):
        if entry.get('type_name') == full:
            return entry.get('hash_string', '')
    return ''

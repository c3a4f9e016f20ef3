"""
Reading a scene's YAML within bounds, so that no file can hang or exhaust the loader.

A scene file is read only if it is a regular file, and at most :data:`MAX_BYTES` of it (so
``/dev/zero``, a FIFO with no writer or a huge file are refused at once). Before anything is
built, the YAML event stream is checked in one pass, without recursion: nesting deeper than
:data:`MAX_DEPTH` (the schema needs 4) and aliases that would expand beyond
:data:`MAX_NODES` nodes (a kilobyte "billion laughs" file) are refused. Syntax errors become
one line with the line and column.
"""
from __future__ import annotations

import os
from pathlib import Path
import stat
from typing import Any

from modal_spring_ros.core.model.scene import SceneError
import yaml

#: Largest scene file read, bytes (explicit positions of 100k particles take about 3 MB).
MAX_BYTES = 16 * 1024 * 1024
#: Deepest nesting of lists and mappings accepted (the schema's deepest is 4).
MAX_DEPTH = 16
#: Most nodes the document may expand to, aliases counted at their full size.
MAX_NODES = 5_000_000
#: libyaml's safe loader where PyYAML was built with it (a 100k-particle scene: seconds, not a
#: minute), else PyYAML's own; the same documents, values and errors
LOADER = getattr(yaml, 'CSafeLoader', yaml.SafeLoader)


def read_scene_text(path: Path) -> str:
    """
    Return the text of a scene file: a regular file of at most :data:`MAX_BYTES`, UTF-8.

    :raises SceneError: not a regular file, too large, unreadable or not UTF-8.
    """
    try:
        info = os.stat(path)
    except OSError as exc:
        raise SceneError(f'{path}: cannot read scene file: {exc.strerror or exc}') from None
    if not stat.S_ISREG(info.st_mode):
        kind = 'a folder' if stat.S_ISDIR(info.st_mode) else 'not a regular file'
        raise SceneError(f'{path}: cannot read scene file: {kind}')
    if info.st_size > MAX_BYTES:
        raise SceneError(f'{path}: scene file of {info.st_size} bytes is larger than the '
                         f'{MAX_BYTES // (1024 * 1024)} MiB a scene may have')
    try:
        with open(path, 'rb') as fh:
            raw = fh.read(MAX_BYTES + 1)
    except OSError as exc:
        raise SceneError(f'{path}: cannot read scene file: {exc.strerror or exc}') from None
    if len(raw) > MAX_BYTES:  # grew while being read
        raise SceneError(f'{path}: scene file larger than the '
                         f'{MAX_BYTES // (1024 * 1024)} MiB a scene may have')
    try:
        return raw.decode('utf-8')
    except UnicodeDecodeError as exc:
        raise SceneError(f'{path}: scene file is not UTF-8 text (byte {exc.start})') from None


def load_yaml(text: str, source: str) -> Any:
    """
    ``yaml.safe_load`` of ``text`` once its structure is within bounds.

    :raises SceneError: too large, nested too deep, aliases expanding too far, or invalid YAML
        (one line, with line and column).
    """
    if len(text) > MAX_BYTES:
        raise SceneError(f'{source}: scene text larger than the '
                         f'{MAX_BYTES // (1024 * 1024)} MiB a scene may have')
    try:
        _check_structure(text, source)
        return yaml.load(text, Loader=LOADER)    # a safe loader: plain data only
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f' at line {mark.line + 1}, column {mark.column + 1}' if mark else ''
        problem = ' '.join(str(exc.problem or exc.context or 'syntax error').split())
        raise SceneError(f'{source}: invalid YAML{where}: {problem}') from None
    except yaml.YAMLError as exc:
        raise SceneError(f"{source}: invalid YAML: {' '.join(str(exc).split())}") from None


def _check_structure(text: str, source: str) -> None:
    """
    One pass over the events.

    Depth, and the size every node expands to (an alias counts the size of what it names, so nested
    aliases multiply as they would when built).
    """
    sizes: dict[str, int] = {}        # anchor -> expanded size of its node
    open_nodes: list[list] = []       # per open collection: [anchor, size so far]
    total = 0
    for event in yaml.parse(text, Loader=LOADER):
        if isinstance(event, yaml.AliasEvent):
            size = sizes.get(event.anchor, 1)
        elif isinstance(event, yaml.ScalarEvent):
            size = 1
            if event.anchor:
                sizes[event.anchor] = 1
        elif isinstance(event, (yaml.SequenceStartEvent, yaml.MappingStartEvent)):
            open_nodes.append([event.anchor, 1])
            if len(open_nodes) > MAX_DEPTH:
                raise SceneError(f'{source}: nested deeper than {MAX_DEPTH} levels (a scene '
                                 'needs 4)')
            continue
        elif isinstance(event, (yaml.SequenceEndEvent, yaml.MappingEndEvent)):
            anchor, size = open_nodes.pop()
            if anchor:
                sizes[anchor] = size
        else:
            continue
        if open_nodes:
            open_nodes[-1][1] += size
        else:
            total += size
        if total + sum(n[1] for n in open_nodes[-1:]) > MAX_NODES or size > MAX_NODES:
            raise SceneError(f'{source}: aliases expand to more than {MAX_NODES:,} values '
                             '(a scene needs a few per particle)')

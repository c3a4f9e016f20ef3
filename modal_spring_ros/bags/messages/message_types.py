"""
ROS message type names, and the installed message classes they may resolve to.

A type name comes from input: a bag's schema, a topic another process advertises on the graph.
It never chooses what Python imports. A name resolves to a class only when

1. it is a ROS interface name (``package/msg/Type``, or ``package/Type`` for ``msg``): a
   package name as ROS allows it (lowercase letters, digits, underscores) and a type name in
   CamelCase, nothing else (no dots, no path);
2. the package is an interface package installed in the ament index (its ``rosidl_interfaces``
   resource lists ``msg/Type.msg`` or ``.idl``): the allow-list is what the ROS install, the
   PyPI wheels or a colcon workspace declare, not a list of our own;
3. the Python package found for it lies under the prefix that index entry belongs to (a
   same-named module elsewhere on the path, e.g. in the working directory, is not imported).

Only then is ``package.msg`` imported. Anything else is refused with :class:`TypeRefused`.
"""
from __future__ import annotations

import importlib
import importlib.util
import os
from pathlib import Path
import re

from modal_spring_ros.scenes.ament_index import package_prefix

#: A ROS interface name: package (as ROS names packages), kind, CamelCase type.
TYPE_NAME = re.compile(r'(?P<package>[a-z][a-z0-9_]*)/(?:(?P<kind>msg|srv|action)/)?'
                       r'(?P<name>[A-Z][A-Za-z0-9]*)')
#: The ament index resource that lists a package's interfaces.
INTERFACES = Path('share') / 'ament_index' / 'resource_index' / 'rosidl_interfaces'


class TypeRefused(LookupError):
    """A message type name that is malformed, or not an installed interface."""


def split_type_name(type_name: str) -> tuple[str, str, str]:
    """
    Return ``(package, kind, name)`` of a ROS interface name (``kind`` is ``msg`` if omitted).

    :raises TypeRefused: not of the form ``package/msg/Type`` (or ``package/Type``).
    """
    match = TYPE_NAME.fullmatch(type_name) if isinstance(type_name, str) else None
    if match is None:
        raise TypeRefused(f'{str(type_name)[:80]!r} is not a ROS message type name '
                          '(package/msg/Type)')
    return match['package'], match['kind'] or 'msg', match['name']


def installed_interface(type_name: str) -> tuple[str, str, str]:
    """
    Return ``(package, kind, name)`` where the ament index lists the type as installed.

    :raises TypeRefused: malformed, or no installed interface package lists it.
    """
    package, kind, name = split_type_name(type_name)
    prefix = package_prefix(package)
    listed = _interfaces(prefix, package) if prefix is not None else set()
    if not {f'{kind}/{name}.msg', f'{kind}/{name}.idl'} & listed:
        raise TypeRefused(f'message type {type_name} is not installed (no interface package '
                          f'{package} listing it in the ament index)')
    spec = importlib.util.find_spec(package)
    origin = spec.origin if spec is not None else None
    if origin is None or not _under(Path(origin), prefix):
        raise TypeRefused(f'message type {type_name}: the Python package {package} found '
                          f'({origin}) is not the one installed under {prefix}')
    return package, kind, name


def message_class(type_name: str):
    """
    Return the rclpy class of an installed message type.

    :raises TypeRefused: see the module's rules; nothing is imported for a refused name.
    """
    package, kind, name = installed_interface(type_name)
    try:
        return getattr(importlib.import_module(f'{package}.{kind}'), name)
    except (ImportError, AttributeError):
        raise TypeRefused(f'message type {type_name} is not installed') from None


def _interfaces(prefix: Path, package: str) -> set[str]:
    """Return the interface files the index lists for ``package`` under ``prefix`` (or none)."""
    try:
        text = (prefix / INTERFACES / package).read_text(encoding='utf-8')
    except (OSError, UnicodeDecodeError):
        return set()
    return {line.strip() for line in text.splitlines() if line.strip()}


def _under(path: Path, prefix: Path) -> bool:
    """Tell whether ``path`` lies under ``prefix`` (links resolved)."""
    try:
        return Path(os.path.realpath(path)).is_relative_to(os.path.realpath(prefix))
    except (OSError, ValueError):
        return False

"""
The architecture as the layout shows it.

Layers that import only downward, no import cycle, a numerical core free of ROS, MCAP and plotting
that neither reads the environment nor writes files, every force model registered, and modules of
a readable size.
"""
from __future__ import annotations

import ast
import importlib
import json
import re
import subprocess
import sys

from helpers import REPO
import pytest

PACKAGE = 'modal_spring_ros'
#: the layers, lowest first: a module may import from its own layer and the ones before it
LAYERS = ['core', 'scenes', 'runs', 'bags', 'ros', 'bench', 'cli']
MAX_MODULE_LINES = 400
MAX_NODE_LINES = 250
#: the ROS layer's rooms, lowest first (the top-level modules are rooms of their own): a room
#: imports from the rooms before it only
ROS_ROOMS = ['process', 'frames', 'markers', 'parameters', 'changes', 'inputs', 'stream', 'start',
             'tools', 'node', 'managed_node']
#: most modules side by side in one folder: beyond it, rooms by concept
MAX_FOLDER_MODULES = 12


def _modules() -> dict[str, object]:
    """Dotted name -> path of every module of the package."""
    out = {}
    for path in sorted((REPO / PACKAGE).rglob('*.py')):
        parts = list(path.relative_to(REPO).with_suffix('').parts)
        if parts[-1] == '__init__':
            parts.pop()
        out['.'.join(parts)] = path
    return out


def _imports(path) -> set[str]:
    """Modules of the package that ``path`` imports (anywhere in it), as dotted names."""
    found = set()
    modules = _modules()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module \
                and node.module.split('.')[0] == PACKAGE:
            for alias in node.names:  # "from pkg.sub import module" imports that module
                full = f'{node.module}.{alias.name}'
                found.add(full if full in modules else node.module)
        elif isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.split('.')[0] == PACKAGE)
        elif isinstance(node, ast.ImportFrom) and node.level > 0:
            raise AssertionError(f'{path}: relative import; the package uses absolute ones')
    return found


def _graph() -> dict[str, set[str]]:
    return {name: _imports(path) for name, path in _modules().items()}


def _layer(module: str) -> int:
    parts = module.split('.')
    return LAYERS.index(parts[1]) if len(parts) > 1 else -1  # the package root is below all


def test_every_module_is_in_a_layer():
    stray = [m for m in _modules() if m != PACKAGE and m.split('.')[1] not in LAYERS]
    assert not stray, f'modules outside the layers {LAYERS}: {stray}'


def test_imports_go_only_downward():
    upward = [f'{m} -> {d}' for m, deps in _graph().items() for d in deps
              if _layer(d) > _layer(m)]
    assert not upward, 'imports from a lower layer to a higher one:\n' + '\n'.join(upward)


def test_no_import_cycle():
    graph = _graph()
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    cycles = []

    def visit(module: str, path: list[str]) -> None:
        state[module] = 1
        for dep in sorted(graph.get(module, ())):
            if state.get(dep) == 1:
                cycles.append(' -> '.join(path[path.index(dep):] + [dep]))
            elif dep not in state:
                visit(dep, path + [dep])
        state[module] = 2

    for module in sorted(graph):
        if module not in state:
            visit(module, [module])
    assert not cycles, 'import cycles:\n' + '\n'.join(cycles)


def test_the_checks_see_a_violation():
    """The graph really is read: the node imports the core, the core imports no layer above."""
    graph = _graph()
    assert 'modal_spring_ros.core.factory' in graph['modal_spring_ros.ros.node']
    assert _layer('modal_spring_ros.ros.node') > _layer('modal_spring_ros.core.factory')


def _ros_room(module: str) -> int:
    return ROS_ROOMS.index(module.split('.')[2])


def test_the_ros_rooms_import_only_downward():
    """``ros/`` is in rooms by concept; a room imports from the rooms before it only."""
    ros = {m: deps for m, deps in _graph().items() if m.startswith(f'{PACKAGE}.ros.')}
    assert {m.split('.')[2] for m in ros} == set(ROS_ROOMS)
    upward = [f'{m} -> {d}' for m, deps in ros.items() for d in deps
              if d.startswith(f'{PACKAGE}.ros.') and _ros_room(d) > _ros_room(m)]
    assert not upward, 'imports from a lower ROS room to a higher one:\n' + '\n'.join(upward)
    # the check sees what it looks for: the node imports the stream room, not the reverse
    assert any(d.startswith(f'{PACKAGE}.ros.stream.') for d in ros[f'{PACKAGE}.ros.node'])
    assert _ros_room(f'{PACKAGE}.ros.node') > _ros_room(f'{PACKAGE}.ros.stream.outputs')


def test_every_room_says_what_it_holds_and_no_folder_is_crowded():
    """Each subpackage has a docstring; no folder holds more than a dozen modules side by side."""
    for init in (REPO / PACKAGE).rglob('__init__.py'):
        doc = ast.get_docstring(ast.parse(init.read_text()))
        assert doc and len(doc.split()) >= 5, f'{init}: a room says what it holds'
    crowded = {}
    for folder in {p.parent for p in (REPO / PACKAGE).rglob('*.py')}:
        count = len([p for p in folder.glob('*.py') if p.name != '__init__.py'])
        if count > MAX_FOLDER_MODULES:
            crowded[str(folder.relative_to(REPO))] = count
    assert not crowded, f'folders beyond {MAX_FOLDER_MODULES} modules: {crowded}'


def test_the_core_imports_no_ros_mcap_or_matplotlib():
    """In a fresh interpreter, importing every core module loads none of them."""
    core = [m for m in _modules() if m.startswith(f'{PACKAGE}.core')]
    code = ('import json, sys\n'
            + ''.join(f'import {m}\n' for m in core)
            + 'print(json.dumps(sorted(m for m in sys.modules '
              "if m.split('.')[0] in ('rclpy', 'mcap', 'mcap_ros2', 'matplotlib'))))")
    proc = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          timeout=120, cwd=REPO)
    assert proc.returncode == 0, proc.stderr
    assert len(core) > 15
    assert json.loads(proc.stdout) == []


#: names whose use reads the environment or touches files
ENVIRONMENT_OR_FILES = {'os.environ', 'os.getenv', 'os.putenv', 'os.replace', 'os.rename',
                        'os.remove', 'os.unlink', 'os.mkdir', 'os.makedirs', 'os.rmdir',
                        'np.save', 'np.savez', 'np.savez_compressed', 'np.savetxt', 'np.load',
                        'np.loadtxt', 'np.fromfile', 'numpy.save', 'numpy.load', 'open'}
#: modules whose import says the same
FILE_MODULES = {'pathlib', 'shutil', 'tempfile', 'glob', 'io'}
#: methods of paths and files that write
WRITING_METHODS = {'write_text', 'write_bytes', 'mkdir', 'unlink', 'touch', 'rmdir', 'tofile'}


def _dotted(node) -> str:
    """Return ``a.b.c`` of a name or attribute chain, else ''."""
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        base = _dotted(node.value)
        return f'{base}.{node.attr}' if base else ''
    return ''


def _environment_or_files(source: str) -> list[str]:
    """Return what in ``source`` reads the environment or touches files (``line: name``)."""
    found = []
    for node in ast.walk(ast.parse(source)):
        name = ''
        if isinstance(node, (ast.Name, ast.Attribute)) and _dotted(node) in ENVIRONMENT_OR_FILES:
            name = _dotted(node)
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) \
                and node.func.attr in WRITING_METHODS:
            name = f'.{node.func.attr}()'
        elif isinstance(node, ast.Import):
            name = ', '.join(a.name for a in node.names if a.name.split('.')[0] in FILE_MODULES)
        elif isinstance(node, ast.ImportFrom) \
                and (node.module or '').split('.')[0] in FILE_MODULES:
            name = node.module
        if name:
            found.append(f'{node.lineno}: {name}')
    return found


def test_the_core_neither_reads_the_environment_nor_writes_files():
    """Environment variables, caches and files are the front ends' (the core is handed them)."""
    core = {m: p for m, p in _modules().items() if m.startswith(f'{PACKAGE}.core')}
    found = {m: hits for m, p in core.items() if (hits := _environment_or_files(p.read_text()))}
    assert not found, f'the core reads the environment or touches files: {found}'
    # the check sees what it looks for
    assert _environment_or_files('import os\nx = os.environ.get("A")\n') == ['2: os.environ']
    assert _environment_or_files('from pathlib import Path\n') == ['1: pathlib']
    assert _environment_or_files('p.write_bytes(b"")\nopen("f", "w")\n') == [
        '1: .write_bytes()', '2: open']


def _concrete(room: str, contract: type) -> dict[str, type]:
    """Return the concrete subclasses of ``contract`` defined in ``core/<room>``, by name."""
    import inspect
    found = {}
    for module in _modules():
        if module.startswith(f'{PACKAGE}.core.{room}'):
            for _, cls in inspect.getmembers(importlib.import_module(module), inspect.isclass):
                if issubclass(cls, contract) and not inspect.isabstract(cls) \
                        and cls.__module__ == module:
                    found[cls.__name__] = cls
    return found


@pytest.mark.parametrize('room', ['forces', 'laws'])
def test_every_force_model_and_spring_law_is_registered(room):
    """Every concrete force model (spring law) of its room is in its registry by its own name."""
    from modal_spring_ros.core.forces import FORCES, ForceModel
    from modal_spring_ros.core.laws import SPRING_LAWS, SpringLaw
    registry, contract, least = {'forces': (FORCES, ForceModel, 3),
                                 'laws': (SPRING_LAWS, SpringLaw, 1)}[room]
    classes = _concrete(room, contract)
    assert len(classes) >= least
    for cls in classes.values():
        assert registry.get(cls.name) is cls, f'{cls.__name__} is not registered as {cls.name!r}'
    assert sorted(registry) == sorted(cls.name for cls in classes.values())


def test_the_spring_laws_import_nothing_of_the_engine():
    """A law is the springs' formula alone: every other part asks it, it asks none."""
    graph = _graph()
    for module, imported in graph.items():
        if module.startswith(f'{PACKAGE}.core.laws'):
            outside = {m for m in imported if not m.startswith(f'{PACKAGE}.core.laws')}
            assert not outside, f'{module} imports {outside}'
    assert any(f'{PACKAGE}.core.laws' in m for m in graph[f'{PACKAGE}.core.forces.springs'])


def test_modules_stay_readable():
    sizes = {m: len(p.read_text().splitlines()) for m, p in _modules().items()}
    big = {m: n for m, n in sizes.items() if n > MAX_MODULE_LINES}
    assert not big, f'modules over {MAX_MODULE_LINES} lines: {big}'
    assert sizes[f'{PACKAGE}.ros.node'] < MAX_NODE_LINES


def test_one_module_per_console_script_named_after_it():
    """Each script starts in the launcher (Ctrl-C guarded) and runs its own module's main."""
    from modal_spring_ros.cli import launcher
    scripts = re.findall(r"'(\w+) = (modal_spring_ros\.[\w.]+):(\w+)'",
                         (REPO / 'setup.py').read_text())
    assert sorted(name for name, _, _ in scripts) == sorted(launcher.SCRIPTS)
    for name, module, function in scripts:
        assert (module, function) == (f'{PACKAGE}.cli.launcher', name), name
        assert callable(getattr(launcher, name))
        assert (REPO / PACKAGE / 'cli' / f'{name}.py').is_file()
        assert callable(importlib.import_module(f'{PACKAGE}.cli.{name}').main)

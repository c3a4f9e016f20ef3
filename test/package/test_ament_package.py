"""
The package as ROS tooling sees it.

Package.xml, its rosdep keys, a colcon build, and the launch file and RViz view it installs.

Runs the real tools (catkin_pkg, rosdep, colcon from PyPI) offline: rosdep reads only the
rosdep file this package ships, and colcon builds a copy of the package in a temporary
workspace, as ``colcon build`` does on a ROS 2 install. ``launch`` is not on PyPI, so the
launch file is resolved here as ``ros2 launch`` resolves it, and the node is started with the
command line ``launch_ros`` gives it.
"""
from __future__ import annotations

import ast
import importlib.metadata
import os
from pathlib import Path
import re
import shutil
import subprocess
import sys

from catkin_pkg.package import parse_package
from helpers import REPO
from modal_spring_ros.cli.launcher import SCRIPTS
import numpy as np
import pytest
from ros_harness import console_script, node_of, node_with_client, wait_for
import yaml

PACKAGE = 'modal_spring_ros'
#: what ``colcon build`` needs of the source tree (the README copies the whole folder)
SOURCE_ITEMS = ['package.xml', 'setup.py', 'setup.cfg', 'resource', PACKAGE, 'config', 'launch']

#: top-level import -> the package.xml key that provides it
IMPORT_KEYS = {
    'numpy': 'python3-numpy',
    'scipy': 'python3-scipy',
    'yaml': 'python3-yaml',
    'matplotlib': 'python3-matplotlib',
    'mcap': 'python3-mcap-pip',
    'mcap_ros2': 'python3-mcap-ros2-support-pip',
    'trimesh': 'python3-trimesh-pip',
    'meshio': 'python3-meshio-pip',
    'threadpoolctl': 'python3-threadpoolctl-pip',
    'tqdm': 'python3-tqdm',
    'foxglove': 'python3-foxglove-sdk-pip',
    'rclpy': 'rclpy',
    'builtin_interfaces': 'builtin_interfaces',
    'rcl_interfaces': 'rcl_interfaces',
    'std_msgs': 'std_msgs',
    'std_srvs': 'std_srvs',
    'geometry_msgs': 'geometry_msgs',
    'sensor_msgs': 'sensor_msgs',
    'visualization_msgs': 'visualization_msgs',
    'diagnostic_msgs': 'diagnostic_msgs',
    'rosgraph_msgs': 'rosgraph_msgs',
    'tf2_msgs': 'tf2_msgs',
    'tf2_ros': 'tf2_ros',
    'simulation_interfaces': 'simulation_interfaces',
    'lifecycle_msgs': 'lifecycle_msgs',
    'ament_index_python': 'ament_index_python',
}
#: optional imports (guarded by ``except ImportError``, installed by an extra, no rosdep key):
#: the benchmark's peer (``pip install '.[peer]'``: Newton on NVIDIA Warp)
OPTIONAL_IMPORTS = {'newton', 'warp'}
TEST_IMPORT_KEYS = {'pytest': 'python3-pytest', 'rosbags': 'python3-rosbags-pip',
                    'catkin_pkg': 'python3-catkin-pkg', 'ament_flake8': 'ament_flake8',
                    'ament_pep257': 'ament_pep257', 'PIL': 'python3-pil',
                    'websockets': 'python3-websockets-pip'}
#: tools this file runs as ``python -m MODULE``
TEST_TOOL_KEYS = {'colcon': 'python3-colcon-common-extensions', 'rosdep2': 'python3-rosdep',
                  'flake8': 'python3-flake8'}


def _package():
    return parse_package(str(REPO / 'package.xml'))


def _imported_modules(folder: Path) -> set[str]:
    """Top-level modules imported anywhere under ``folder`` (absolute imports)."""
    names = set()
    for path in folder.rglob('*.py'):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                names.update(alias.name.split('.')[0] for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names.add(node.module.split('.')[0])
    return names - set(sys.stdlib_module_names) - {PACKAGE}


def test_package_xml_is_valid_format_3_ament_python():
    package = _package()
    package.validate()
    assert package.package_format == 3
    assert package.name == PACKAGE
    assert package.get_build_type() == 'ament_python'
    assert list(package.licenses) == ['Apache-2.0']


def test_every_module_the_package_imports_is_a_declared_run_dependency():
    declared = {d.name for d in _package().exec_depends}
    imported = _imported_modules(REPO / PACKAGE) - OPTIONAL_IMPORTS
    unknown = imported - IMPORT_KEYS.keys()
    assert not unknown, f'imports with no package.xml key known to this test: {unknown}'
    missing = {IMPORT_KEYS[m] for m in imported} - declared
    assert not missing, f'imported but not <exec_depend> in package.xml: {missing}'


def test_every_module_the_tests_import_is_declared():
    package = _package()
    declared = {d.name for d in package.exec_depends + package.test_depends}
    local = {path.stem for path in (REPO / 'test').rglob('*.py')}   # the tests' own helpers
    imported = _imported_modules(REPO / 'test') - local
    unknown = imported - IMPORT_KEYS.keys() - TEST_IMPORT_KEYS.keys()
    assert not unknown, f'test imports with no package.xml key known to this test: {unknown}'
    needed = {({**IMPORT_KEYS, **TEST_IMPORT_KEYS})[m] for m in imported}
    needed |= set(TEST_TOOL_KEYS.values())
    missing = needed - declared
    assert not missing, f'needed by the tests but not declared in package.xml: {missing}'


# -- rosdep ------------------------------------------------------------------------------------

@pytest.fixture(scope='module')
def rosdep_env(tmp_path_factory):
    """Return an offline rosdep whose only source is the rosdep file this package ships."""
    root = tmp_path_factory.mktemp('rosdep')
    (root / 'sources').mkdir()
    (root / 'sources' / '50-modal-spring-ros.list').write_text(
        f"yaml {(REPO / 'resource' / 'rosdep.yaml').as_uri()}\n")
    (root / 'index' / 'jazzy').mkdir(parents=True)
    (root / 'index' / 'index-v4.yaml').write_text(yaml.safe_dump({
        'type': 'index', 'version': 4,
        'distributions': {'jazzy': {'distribution': ['jazzy/distribution.yaml'],
                                    'distribution_status': 'active',
                                    'distribution_type': 'ros2', 'python_version': 3}}}))
    (root / 'index' / 'jazzy' / 'distribution.yaml').write_text(yaml.safe_dump({
        'type': 'distribution', 'version': 2, 'repositories': {},
        'release_platforms': {'ubuntu': ['noble']}}))
    env = {**os.environ, 'ROSDEP_SOURCE_PATH': str(root / 'sources'), 'ROS_HOME': str(root),
           'ROSDISTRO_INDEX_URL': (root / 'index' / 'index-v4.yaml').as_uri()}
    rosdep = [sys.executable, '-m', 'rosdep2']  # see TEST_TOOL_KEYS
    update = subprocess.run(rosdep + ['update', '--rosdistro', 'jazzy'], env=env,
                            capture_output=True, text=True, timeout=120)
    assert update.returncode == 0, update.stdout + update.stderr
    return rosdep, env


def _pip_requirements() -> set[str]:
    """Lower-case names of the installed package's requirements (install, view, test)."""
    out = set()
    for req in importlib.metadata.requires(PACKAGE) or []:
        if 'extra ==' in req and not ('extra == "test"' in req or 'extra == "view"' in req):
            continue
        out.add(re.split(r'[\s\[<>=!;~]', req, maxsplit=1)[0].lower())
    return out


@pytest.mark.ros
@pytest.mark.slow
def test_the_shipped_rosdep_file_resolves_every_pip_key_to_a_package_setup_py_requires(
        rosdep_env):
    rosdep, env = rosdep_env
    package = _package()
    pip_keys = sorted({d.name for d in package.exec_depends + package.test_depends
                       if d.name.endswith('-pip')})
    assert pip_keys == ['python3-foxglove-sdk-pip', 'python3-mcap-pip',
                        'python3-mcap-ros2-support-pip', 'python3-meshio-pip',
                        'python3-rosbags-pip', 'python3-threadpoolctl-pip',
                        'python3-trimesh-pip', 'python3-websockets-pip']
    requirements = _pip_requirements()
    for key in pip_keys:
        done = subprocess.run(rosdep + ['resolve', key, '--os=ubuntu:noble',
                                        '--rosdistro=jazzy'],
                              env=env, capture_output=True, text=True, timeout=60)
        assert done.returncode == 0, done.stdout + done.stderr
        installer, name = done.stdout.split()
        assert installer == '#pip'
        assert name.lower() in requirements, (key, name, requirements)


@pytest.mark.ros
@pytest.mark.slow
def test_rosdep_names_a_key_it_cannot_resolve(rosdep_env):
    rosdep, env = rosdep_env
    done = subprocess.run(rosdep + ['resolve', 'python3-not-a-key-pip', '--os=ubuntu:noble',
                                    '--rosdistro=jazzy'],
                          env=env, capture_output=True, text=True, timeout=60)
    assert done.returncode != 0
    assert 'python3-not-a-key-pip' in done.stdout + done.stderr


# -- colcon ------------------------------------------------------------------------------------

@pytest.fixture(scope='module')
def colcon_install(tmp_path_factory) -> Path:
    """``colcon build`` of a copy of the package; returns the install folder."""
    ws = tmp_path_factory.mktemp('colcon_ws')
    src = ws / 'src' / PACKAGE
    src.mkdir(parents=True)
    for item in SOURCE_ITEMS:
        if (REPO / item).is_dir():
            shutil.copytree(REPO / item, src / item,
                            ignore=shutil.ignore_patterns('__pycache__'))
        else:
            shutil.copy2(REPO / item, src / item)
    done = subprocess.run(
        [sys.executable, '-m', 'colcon', '--log-base', str(ws / 'log'), 'build',
         '--base-paths', str(ws / 'src'), '--build-base', str(ws / 'build'),
         '--install-base', str(ws / 'install')],
        cwd=ws, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    return ws / 'install'


def _console_scripts() -> list[str]:
    eps = importlib.metadata.distribution(PACKAGE).entry_points
    return sorted(ep.name for ep in eps if ep.group == 'console_scripts')


@pytest.mark.ros
@pytest.mark.slow
def test_colcon_build_installs_the_ament_layout(colcon_install):
    prefix = colcon_install / PACKAGE
    scripts = _console_scripts()
    assert 'modal_spring_node' in scripts and len(scripts) == len(SCRIPTS)
    for name in scripts:  # where `ros2 run modal_spring_ros NAME` looks
        exe = prefix / 'lib' / PACKAGE / name
        assert exe.is_file() and os.access(exe, os.X_OK), exe
    assert (prefix / 'share' / 'ament_index' / 'resource_index' / 'packages' / PACKAGE).is_file()
    share = prefix / 'share' / PACKAGE
    assert (share / 'package.xml').read_text() == (REPO / 'package.xml').read_text()
    for pattern in ('config/*.yaml', 'config/*.rviz', 'config/*.xml', 'config/scenes/*.yaml',
                    'launch/*.launch.yaml'):
        shipped = sorted(p.name for p in REPO.glob(pattern))
        assert shipped and sorted(p.name for p in share.glob(pattern)) == shipped


def _sourced(install: Path, command: str) -> subprocess.CompletedProcess:
    """``command`` in bash after sourcing the workspace, with none of the test's own paths."""
    env = {k: v for k, v in os.environ.items()
           if k not in ('PYTHONPATH', 'AMENT_PREFIX_PATH', 'COLCON_PREFIX_PATH')}
    return subprocess.run(['bash', '-c', f". '{install}/setup.sh' && {command}"], env=env,
                          cwd=install.parent, capture_output=True, text=True, timeout=120)


@pytest.mark.ros
@pytest.mark.slow
def test_the_installed_package_finds_its_files_through_the_ament_index(colcon_install):
    probe = _sourced(colcon_install, f"'{sys.executable}' -c \""
                     'import modal_spring_ros.scenes.resources as s;'
                     ' from ament_index_python.packages import get_package_prefix as p;'
                     ' print(s.__file__); print(s.builtin_scene_dir());'
                     f" print(p('{PACKAGE}')); print(s.executable('modal_spring_node'))\"")
    assert probe.returncode == 0, probe.stderr
    module, scenes, prefix, node = probe.stdout.split()
    install = str(colcon_install / PACKAGE)
    assert module.startswith(install + '/lib/')     # not the source tree's copy
    assert scenes == f'{install}/share/{PACKAGE}/config/scenes'
    assert prefix == install
    # where `ros2 run` looks, not beside the interpreter (a system Python has none there)
    assert node == f'{install}/lib/{PACKAGE}/modal_spring_node'


def test_scripts_are_found_in_the_ament_prefix_else_beside_the_interpreter(tmp_path):
    prefix = tmp_path / 'prefix'  # an install prefix of another workspace, as colcon makes it
    index = prefix / 'share' / 'ament_index' / 'resource_index' / 'packages'
    index.mkdir(parents=True)
    (index / PACKAGE).write_text('')
    script = prefix / 'lib' / PACKAGE / 'modal_spring_sim'
    script.parent.mkdir(parents=True)
    script.write_text('#!/bin/sh\n')
    code = ('from modal_spring_ros.scenes.resources import executable; '
            "print(executable('modal_spring_sim'))")

    def found(**env):
        base = {k: v for k, v in os.environ.items() if k != 'AMENT_PREFIX_PATH'}
        return subprocess.run([sys.executable, '-c', code], env={**base, **env},
                              capture_output=True, text=True, timeout=60)
    assert found(AMENT_PREFIX_PATH=str(prefix)).stdout.strip() == str(script)
    beside = Path(sys.executable).parent / 'modal_spring_sim'  # a venv's bin
    without = found()
    if beside.is_file():
        assert without.stdout.strip() == str(beside)
    else:  # a system interpreter: nothing to fall back to, and the error says where it looked
        assert without.returncode != 0 and 'modal_spring_sim is not installed' in without.stderr


@pytest.mark.ros
@pytest.mark.slow
def test_an_installed_console_script_runs_a_built_in_scene(colcon_install, tmp_path):
    exe = colcon_install / PACKAGE / 'lib' / PACKAGE / 'modal_spring_sim'
    out = tmp_path / 'run.npz'
    run = _sourced(colcon_install, f"'{exe}' --scene chain_2 --duration 0.05 --quiet "
                   f"--output '{out}'")
    assert run.returncode == 0, run.stderr
    assert 'chain_2' in run.stdout
    with np.load(out) as data:
        assert data['positions'].shape == (51, 3, 3)
        assert np.all(np.isfinite(data['positions']))


# -- launch file and RViz view -----------------------------------------------------------------

LAUNCH_FILE = 'launch/modal_spring.launch.yaml'
RVIZ_FILE = 'config/modal_spring.rviz'
_SUBSTITUTION = re.compile(r'\$\(([a-z-]+) ([^)]*)\)')


def _launch_actions(share: Path, **arguments: str) -> list[tuple[str, dict]]:
    """
    Return the launch file's actions as ``ros2 launch`` leaves them.

    The launch file's actions as ``ros2 launch PACKAGE modal_spring.launch.yaml NAME:=VALUE``
    leaves them: ``$(var NAME)`` is the argument's value (its default unless given),
    ``$(find-pkg-share PACKAGE)`` the installed ``share`` folder, and an action whose ``if`` is
    false is dropped. Any other substitution fails the test rather than being guessed at.
    """
    entries = yaml.safe_load((share / LAUNCH_FILE).read_text())['launch']
    declared = [entry['arg']['name'] for entry in entries if 'arg' in entry]
    assert set(arguments) <= set(declared), f'undeclared launch arguments {arguments}'
    values: dict[str, str] = {}

    def resolve(value):
        if isinstance(value, dict):
            return {k: resolve(v) for k, v in value.items()}
        if isinstance(value, list):
            return [resolve(v) for v in value]
        if not isinstance(value, str):
            return value

        def one(match):
            kind, name = match.groups()
            if kind == 'var':
                return values[name]
            assert kind == 'find-pkg-share' and name == PACKAGE, match.group(0)
            return str(share)
        return _SUBSTITUTION.sub(one, value)

    actions = []
    for entry in entries:
        (kind, body), = entry.items()
        if kind == 'arg':  # defaults may use earlier arguments and substitutions
            values[body['name']] = arguments.get(body['name'], resolve(str(body['default'])))
            continue
        body = resolve(body)
        condition = str(body.pop('if', 'true')).lower()
        assert condition in ('true', 'false', '1', '0')  # what launch's IfCondition accepts
        if condition in ('true', '1'):
            actions.append((kind, body))
    return actions


def _node_command(node: dict, tmp_path: Path) -> list[str]:
    """
    Return the command line launch_ros runs for a ``node`` action.

    The executable and its ``args``, then ``--ros-args``, the node name, and one ``--params-file``
    per parameter source in order, the ``from`` files first and the name/value pairs (written to a
    file of their own under ``/**``) last, so that those win.
    """
    command = [console_script(node['exec']), *node.get('args', '').split(), '--ros-args',
               '-r', f"__node:={node['name']}"]
    files = [p['from'] for p in node.get('param', []) if 'from' in p]
    pairs = {p['name']: p['value'] for p in node.get('param', []) if 'from' not in p}
    if pairs:
        overrides = tmp_path / 'launch_params.yaml'
        overrides.write_text(yaml.safe_dump({'/**': {'ros__parameters': pairs}}))
        files.append(str(overrides))
    for path in files:
        command += ['--params-file', path]
    return command


@pytest.mark.ros
@pytest.mark.slow
def test_the_launch_file_starts_the_node_with_its_arguments(colcon_install, tmp_path):
    from diagnostic_msgs.msg import DiagnosticArray
    from modal_spring_ros.ros.node import NODE_NAME
    from modal_spring_ros.ros.stream.outputs import POINTS_TOPIC
    from modal_spring_ros.scenes.resources import load_scene
    from sensor_msgs.msg import PointCloud2
    share = colcon_install / PACKAGE / 'share' / PACKAGE
    actions = _launch_actions(share, scene='cantilever_3d')
    assert [(kind, body['pkg']) for kind, body in actions] == [('node', PACKAGE)]  # no RViz
    node = actions[0][1]
    assert node['name'] == NODE_NAME and 'namespace' not in node and 'remap' not in node
    # the installed parameter file, then the scene argument over the file's sheet_10x10
    assert node['param'][0]['from'] == str(share / 'config' / 'modal_spring.yaml')
    with node_with_client(namespace='launch', argv=_node_command(node, tmp_path)) as (_, client):
        diagnostics = client.collect(DiagnosticArray, '/diagnostics')
        clouds = client.collect(PointCloud2, '/' + POINTS_TOPIC)

        def ours():              # once it streams (before, it says what it prepares)
            return [d.status[0] for _, d in list(diagnostics)
                    if node_of(d.status[0]) == f'/{NODE_NAME}'
                    and not d.status[0].message.startswith('starting: ')]
        assert wait_for(lambda: ours() and clouds, 60)
        status = ours()[-1]
        values = {kv.key: kv.value for kv in status.values}
        assert status.hardware_id == 'cantilever_3d'             # the launch argument
        assert values['band'] == 'allpass'          # the parameter file: the node's defaults
        assert clouds[-1][1].width == load_scene('cantilever_3d').n_particles


@pytest.mark.ros
@pytest.mark.slow
def test_rviz_starts_only_when_asked_with_the_installed_view(colcon_install):
    from modal_spring_ros.scenes.resources import DEFAULT_SCENE
    share = colcon_install / PACKAGE / 'share' / PACKAGE
    # `ros2 launch PACKAGE FILE` looks for FILE anywhere in the package's share folder
    assert list(share.rglob(Path(LAUNCH_FILE).name)) == [share / LAUNCH_FILE]
    default = _launch_actions(share)
    assert [body['pkg'] for _, body in default] == [PACKAGE]
    assert default[0][1]['param'][1] == {'name': 'scene', 'value': DEFAULT_SCENE}
    assert all(body['pkg'] == PACKAGE for _, body in _launch_actions(share, rviz='false'))
    rviz = [body for _, body in _launch_actions(share, rviz='true') if body['pkg'] == 'rviz2']
    assert len(rviz) == 1 and rviz[0]['exec'] == 'rviz2'
    flag, view = rviz[0]['args'].split()
    assert flag == '-d' and Path(view) == share / RVIZ_FILE and Path(view).is_file()
    assert {'ros2launch', 'rviz2'} <= {d.name for d in _package().exec_depends}


def test_the_rviz_view_shows_what_the_node_publishes():
    from modal_spring_ros.bags.messages.pointcloud import FIELD_NAMES
    from modal_spring_ros.ros.node import NODE_NAME
    from modal_spring_ros.ros.stream.outputs import MESH_TOPIC, POINTS_TOPIC
    from modal_spring_ros.ros.parameters import PARAMETERS
    view = yaml.safe_load((REPO / RVIZ_FILE).read_text())['Visualization Manager']
    displays = {d['Class']: d for d in view['Displays']}
    cloud = displays['rviz_default_plugins/PointCloud2']
    assert cloud['Topic']['Value'] == '/' + POINTS_TOPIC   # the launch file's root namespace
    assert cloud['Color Transformer'] == 'Intensity'
    assert cloud['Channel Name'] == 'displacement' and 'displacement' in FIELD_NAMES
    assert displays['rviz_default_plugins/Marker']['Topic']['Value'] == '/' + MESH_TOPIC
    assert view['Global Options']['Fixed Frame'] == PARAMETERS['frame_id'][0]
    assert 'rviz_default_plugins/TF' in displays                    # the node's frames
    # RViz's own tools are all there (a Tools list replaces the defaults), Publish Point
    # sending on the topic the node pulls from
    from modal_spring_ros.ros.inputs.input_kinds import CLICKED_POINT
    tools = {t['Class']: t for t in view['Tools']}
    assert tools['rviz_default_plugins/PublishPoint']['Topic']['Value'] == CLICKED_POINT.topic
    assert {'Interact', 'MoveCamera', 'Select', 'FocusCamera', 'Measure', 'SetInitialPose',
            'SetGoal'} <= {name.split('/')[1] for name in tools}
    params = yaml.safe_load((REPO / 'config' / 'modal_spring.yaml').read_text())
    assert list(params) == [f'/**/{NODE_NAME}']              # the launch file's node name


def test_the_rviz_view_looks_at_the_default_sheet_upright_in_a_z_up_world():
    from modal_spring_ros.scenes.resources import DEFAULT_SCENE, load_scene
    scene = load_scene(DEFAULT_SCENE)
    view = yaml.safe_load((REPO / RVIZ_FILE).read_text())['Visualization Manager']
    camera = view['Views']['Current']
    focal = np.array([camera['Focal Point'][k] for k in 'XYZ'], dtype=float)
    low, high = scene.rest_positions.min(axis=0), scene.rest_positions.max(axis=0)
    assert np.all(low <= focal) and np.all(focal <= high)    # centred on the sheet
    # an orbit camera sits along (cos p cos y, cos p sin y, sin p) from its focal point
    pitch, yaw = camera['Pitch'], camera['Yaw']
    eye = np.array([np.cos(pitch) * np.cos(yaw), np.cos(pitch) * np.sin(yaw), np.sin(pitch)])
    normal = ({0, 1, 2} - set(scene.axes)).pop()
    assert normal == 1 and abs(eye[normal]) > 0.9              # facing the hanging sheet
    grid = next(d for d in view['Displays'] if d['Class'] == 'rviz_default_plugins/Grid')
    assert grid['Plane'] == 'XY' and grid['Offset']['Z'] < low[2]   # a floor below it


def test_the_shipped_parameter_file_holds_the_node_s_own_defaults():
    """
    One source of defaults.

    Config/modal_spring.yaml is every parameter at the value the node declares, so a user reading
    it, or launching with it, sees what the node does.
    """
    from modal_spring_ros.ros.parameters import PARAMETERS
    params = yaml.safe_load((REPO / 'config' / 'modal_spring.yaml').read_text())
    values = params['/**/modal_spring']['ros__parameters']
    assert values == {name: default for name, (default, _) in PARAMETERS.items()}


def test_the_large_cloud_profile_sends_a_100k_cloud_through_shared_memory():
    import xml.etree.ElementTree as ET

    from modal_spring_ros.ros.process.shared_memory import PROFILE, SEGMENT_BYTES
    from modal_spring_ros.scenes.resources import load_scene
    ns = {'f': 'http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles'}
    root = ET.parse(REPO / PROFILE).getroot()
    transports = {t.findtext('f:transport_id', namespaces=ns): t
                  for t in root.iterfind('.//f:transport_descriptor', ns)}
    shm = [t for t in transports.values() if t.findtext('f:type', namespaces=ns) == 'SHM']
    cloud = 16 * load_scene('sheet_316x316').n_particles          # the points' bytes
    size = int(shm[0].findtext('f:segment_size', namespaces=ns))
    assert len(shm) == 1 and size > 4 * cloud and size == SEGMENT_BYTES
    participant = root.find('.//f:participant', ns)
    assert participant.get('is_default_profile') == 'true'
    used = [e.text for e in participant.iterfind('.//f:userTransports/f:transport_id', ns)]
    assert set(used) == set(transports)                          # shared memory, then UDPv4
    assert {t.findtext('f:type', namespaces=ns) for t in transports.values()} == {'SHM', 'UDPv4'}

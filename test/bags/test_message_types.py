"""
A message type name is data: it resolves to an installed interface or is refused, never imported.

Bags whose schemas name Python modules (``this/msg/Zen`` prints the Zen of Python when
imported, ``antigravity`` opens a browser) and a ``.py`` file shipped in a bag's folder, run
from inside that folder with a ``PYTHONPATH`` whose empty entry puts it on the import path.
"""
from __future__ import annotations

import os
from pathlib import Path
import subprocess
import sys

from mcap.writer import Writer
from modal_spring_ros.bags.files.reader import BagReader
from modal_spring_ros.bags.files.writer import BagError
from modal_spring_ros.bags.messages.message_types import (message_class, split_type_name,
                                                          TypeRefused)
from modal_spring_ros.ros.tools.installed_messages import installed_message
import pytest
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import String

BIN = Path(sys.executable).parent
#: a module that leaves a mark where it is imported
PLANTED = "open({mark!r}, 'w').write('imported')\nprint('PLANTED CODE RAN')\n"
#: type names a hostile bag could carry
HOSTILE = ('this/msg/Zen', 'antigravity/msg/X', 'evil/msg/X', 'os/msg/Path', 'rclpy/msg/Node',
           'stereo_msgs/msg/Nope')


def _hostile_bag(folder: Path) -> Path:
    """Write a ros2 MCAP file whose channels name the hostile types (a message each)."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / 'hostile_0.mcap'
    with open(path, 'wb') as fh:
        writer = Writer(fh)
        writer.start(profile='ros2', library='test')
        for i, type_name in enumerate(HOSTILE):
            schema = writer.register_schema(type_name, 'ros2msg', b'string data\n')
            channel = writer.register_channel(f'/t{i}', 'cdr', schema)
            writer.add_message(channel, log_time=i, publish_time=i,
                               data=b'\x00\x01\x00\x00\x01\x00\x00\x00\x00')
        writer.finish()
    (folder / 'evil.py').write_text(PLANTED.format(mark=str(folder / 'MARK')))
    return folder


@pytest.mark.parametrize('name, parts', [
    ('sensor_msgs/msg/PointCloud2', ('sensor_msgs', 'msg', 'PointCloud2')),
    ('std_msgs/String', ('std_msgs', 'msg', 'String')),
    ('std_srvs/srv/Trigger', ('std_srvs', 'srv', 'Trigger'))])
def test_ros_interface_names_split_into_package_kind_and_type(name, parts):
    assert split_type_name(name) == parts


@pytest.mark.parametrize('name', [
    '', 'PointCloud2', '../../etc/msg/X', 'sensor_msgs.msg/msg/X', 'sensor_msgs/msg/x',
    'Sensor_msgs/msg/X', 'sensor_msgs/foo/X', 'a/b/c/D', 'sensor_msgs/msg/Point Cloud',
    'sensor_msgs/msg/X\n', None, 3])
def test_malformed_type_names_are_refused(name):
    with pytest.raises(TypeRefused, match='not a ROS message type name'):
        split_type_name(name)


def test_installed_interfaces_resolve_to_their_rclpy_classes():
    assert message_class('sensor_msgs/msg/PointCloud2') is PointCloud2
    assert message_class('std_msgs/String') is String
    assert message_class('tf2_msgs/msg/TFMessage').__name__ == 'TFMessage'


def test_hostile_type_names_import_nothing():
    # in a fresh interpreter: none of the modules they name is imported, nothing is printed
    code = ('import sys\n'
            'from modal_spring_ros.bags.messages.message_types import message_class, TypeRefused\n'
            f'for name in {HOSTILE!r}:\n'
            '    try:\n'
            '        message_class(name)\n'
            '    except TypeRefused as exc:\n'
            '        print("refused:", exc)\n'
            'print(sorted(m for m in ("this", "antigravity", "evil", "webbrowser")\n'
            '             if m in sys.modules))\n')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         timeout=120, check=True).stdout
    assert out.count('refused:') == len(HOSTILE)
    assert out.splitlines()[-1] == '[]'
    assert 'Beautiful is better than ugly' not in out


def test_a_planted_module_shadowing_an_installed_interface_is_not_imported(tmp_path):
    # stereo_msgs is an installed interface package; a stereo_msgs.py first on the path is not
    # the one the index installed: refused, and never run
    mark = tmp_path / 'MARK'
    (tmp_path / 'stereo_msgs.py').write_text(PLANTED.format(mark=str(mark)))
    code = ('import sys; sys.path.insert(0, "")\n'
            'from modal_spring_ros.bags.messages.message_types import message_class, TypeRefused\n'
            'try:\n'
            '    message_class("stereo_msgs/msg/DisparityImage")\n'
            'except TypeRefused as exc:\n'
            '    print("refused:", exc)\n')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         timeout=120, check=True, cwd=tmp_path).stdout
    assert 'refused:' in out and 'is not the one installed' in out
    assert not mark.exists()


def test_the_reader_decodes_a_hostile_type_from_the_bag_s_own_definition_importing_nothing(
        tmp_path):
    bag = BagReader(_hostile_bag(tmp_path / 'bag'))
    assert sorted(info.type_name for info in bag.topics.values()) == sorted(HOSTILE)
    for message in bag.messages():
        assert bag.decode(message).data == ''       # its 'string data', from the bag's schema
        # as an installed class (what ROS code is handed): refused, named
        with pytest.raises(BagError, match=f'{message.topic}: message type '
                                           f'{message.type_name} is not installed'):
            installed_message(bag, message)
    assert not (tmp_path / 'bag' / 'MARK').exists()


@pytest.mark.parametrize('tool, args', [
    ('modal_spring_replay', []),
    ('modal_spring_compare', ['hostile_0.mcap', '--topic', '/t2']),
])
def test_tools_run_inside_a_hostile_bag_folder_run_none_of_its_code(tmp_path, tool, args):
    folder = _hostile_bag(tmp_path / 'downloaded')
    env = dict(os.environ, PYTHONPATH=os.pathsep + os.environ.get('PYTHONPATH', ''))
    done = subprocess.run([str(BIN / tool), 'hostile_0.mcap', *args], cwd=folder, env=env,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    assert not (folder / 'MARK').exists()
    assert 'PLANTED' not in done.stdout + done.stderr
    assert 'Beautiful is better than ugly' not in done.stdout + done.stderr
    assert 'Traceback' not in done.stderr
    assert ('installed message type' in done.stderr or 'not installed' in done.stderr
            or 'not sensor_msgs/msg/PointCloud2' in done.stderr), done.stderr


def test_the_launcher_takes_relative_entries_off_the_import_path(tmp_path):
    code = ('import sys\n'
            'from modal_spring_ros.cli.launcher import safe_path\n'
            'safe_path(); print([p for p in sys.path if not p.startswith("/")])\n')
    env = dict(os.environ, PYTHONPATH=f'.{os.pathsep}{os.pathsep}relative')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         timeout=120, check=True, cwd=tmp_path, env=env).stdout
    assert out.strip() == '[]'

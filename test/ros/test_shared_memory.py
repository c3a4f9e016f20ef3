"""
Large clouds over shared memory (``ros/process/shared_memory.py``), decided and seen in the node.

The choice (the package's large-segment Fast DDS profile unless the user chose, another RMW
runs, or /dev/shm cannot hold it), the start line's sentence for each case, and over DDS: the
node started as users start it has a segment of the profile's size in /dev/shm, and one told
``FASTDDS_BUILTIN_TRANSPORTS=DEFAULT`` does not.
"""
from __future__ import annotations

import os
import signal
import subprocess
import time

from helpers import hanging_sheet
from modal_spring_ros.bags.files.capture import RunBagWriter
from modal_spring_ros.ros.process.shared_memory import (cloud_transport, POINT_BYTES,
                                                        prefer_large_shared_memory, PROFILE,
                                                        PROFILES_VARIABLE, scene_argument,
                                                        SEGMENT_BYTES, SHM_FREE_NEEDED, SHM_PATH)
from modal_spring_ros.scenes.files.declared_size import declared_particles
from modal_spring_ros.scenes.resources import share_directory
from modal_spring_ros.scenes.schema import scene_from_dict
import pytest
from ros_harness import console_script, NodeProcess, wait_for

SHARE = share_directory()
PLENTY = lambda: 10 * SHM_FREE_NEEDED  # noqa: E731
LARGE = 99_856 * POINT_BYTES           # the 100k sheet's 1.6 MB clouds


def test_the_node_takes_the_profile_unless_the_user_chose(tmp_path):
    env: dict[str, str] = {}
    assert prefer_large_shared_memory(SHARE, LARGE, env, tmp_path, PLENTY)
    assert env == {PROFILES_VARIABLE: str(SHARE / PROFILE)}
    assert (SHARE / PROFILE).is_file()
    # the user's own profile, transports, or a default profile file where the node starts
    for chosen in ({PROFILES_VARIABLE: '/mine.xml'}, {'FASTDDS_DEFAULT_PROFILES_FILE': '/m.xml'},
                   {'FASTDDS_BUILTIN_TRANSPORTS': 'LARGE_DATA'}):
        env = dict(chosen)
        assert not prefer_large_shared_memory(SHARE, LARGE, env, tmp_path, PLENTY)
        assert env == chosen
    (tmp_path / 'DEFAULT_FASTRTPS_PROFILES.xml').write_text('<profiles/>')
    env = {}
    assert not prefer_large_shared_memory(SHARE, LARGE, env, tmp_path, PLENTY) and env == {}


@pytest.mark.parametrize('rmw, taken', [('', True), ('rmw_fastrtps_cpp', True),
                                        ('rmw_fastrtps_dynamic_cpp', True),
                                        ('rmw_cyclonedds_cpp', False), ('rmw_zenoh_cpp', False)])
def test_only_fast_dds_gets_a_fast_dds_profile(tmp_path, rmw, taken):
    env = {'RMW_IMPLEMENTATION': rmw} if rmw else {}
    assert prefer_large_shared_memory(SHARE, LARGE, env, tmp_path, PLENTY) == taken
    assert (PROFILES_VARIABLE in env) == taken


def test_only_clouds_beyond_the_default_segment_get_it(tmp_path):
    # the segment is filled when Fast DDS creates it: 32 MB of /dev/shm for every node else
    for size, taken in ((None, False), (1600, False), (524_288, False), (524_289, True)):
        env: dict[str, str] = {}
        assert prefer_large_shared_memory(SHARE, size, env, tmp_path, PLENTY) == taken


def test_the_scene_is_read_from_the_command_line_as_rcl_reads_it(tmp_path):
    params = tmp_path / 'params.yaml'
    params.write_text('/**:\n  ros__parameters:\n    scene: sheet_316x316\n'
                      '    publish_rate_hz: 30.0\n')
    assert scene_argument([], 'sheet_10x10') == 'sheet_10x10'
    assert scene_argument(['--ros-args', '-p', 'scene:=sheet_100x100'], 'x') == 'sheet_100x100'
    assert scene_argument(['--ros-args', '--params-file', str(params)], 'x') == 'sheet_316x316'
    # -p over a parameter file, whatever their order; names of other parameters ignored
    assert scene_argument(['--ros-args', '-p', 'scene:=chain_2', '--params-file', str(params),
                           '--param', 'scene_x:=1'], 'x') == 'chain_2'
    assert scene_argument(['--ros-args', '--params-file', str(tmp_path / 'none.yaml')],
                          'x') == 'x'
    # what each declares, read without building it
    assert declared_particles('sheet_316x316') * POINT_BYTES == LARGE
    assert declared_particles('sheet_10x10') == 100
    assert declared_particles('cloth_3d') == 400
    assert declared_particles('no_such_scene') is None
    (tmp_path / 'listed.yaml').write_text(
        'dimension: 2\nparticles: {positions: [[0, 0, 0], [1, 0, 0], [2, 0, 0]]}\n')
    assert declared_particles(str(tmp_path / 'listed.yaml')) == 3


def test_a_small_dev_shm_keeps_the_default_and_the_start_line_says_how(tmp_path):
    env: dict[str, str] = {}
    small = lambda: 40 << 20      # noqa: E731  a container's 64 MB /dev/shm, partly used
    assert not prefer_large_shared_memory(SHARE, LARGE, env, tmp_path, small) and env == {}
    line = cloud_transport(1_600_000, 'rmw_fastrtps_cpp', SHARE, env, tmp_path, small)
    assert line == ('1.6 MB clouds over UDP loopback: /dev/shm has 40 MB free, the large-cloud '
                    'segment needs 64 MB (a container: --shm-size=256m)')


def test_the_start_line_says_how_large_clouds_travel(tmp_path):
    ours = {PROFILES_VARIABLE: str(SHARE / PROFILE)}
    say = lambda size, rmw='rmw_fastrtps_cpp', env=ours: cloud_transport(  # noqa: E731
        size, rmw, SHARE, env, tmp_path, PLENTY)
    assert say(16 * 10_000) == ''                        # fits the default segment anyway
    assert say(16 * 99_856) == '1.6 MB clouds over shared memory (32 MB segment)'
    assert say(16 * 1_000_000) == (
        '16.0 MB clouds over shared memory, a 32 MB segment holding 2 of them (a profile of '
        f'your own with {PROFILES_VARIABLE} can give more)')
    assert say(16 * 99_856, env={'FASTDDS_BUILTIN_TRANSPORTS': 'DEFAULT'}) == (
        '1.6 MB clouds: their transport is yours (FASTDDS_BUILTIN_TRANSPORTS=DEFAULT)')
    assert say(16 * 99_856, rmw='rmw_cyclonedds_cpp') == (
        '1.6 MB clouds: rmw_cyclonedds_cpp decides their transport (see its shared-memory '
        'settings)')
    assert SEGMENT_BYTES == 32 << 20


def _segments() -> dict[str, int]:
    """Fast DDS's shared-memory segments now in /dev/shm, by name, with their sizes."""
    sizes = {}
    for entry in os.scandir(SHM_PATH):
        if entry.name.startswith('fastrtps_') and not entry.name.endswith('_el'):
            try:
                sizes[entry.name] = entry.stat().st_size
            except FileNotFoundError:
                continue
    return sizes


def _new_segments(before: set[str]) -> dict[str, int]:
    return {name: size for name, size in _segments().items() if name not in before}


@pytest.mark.slow
@pytest.mark.skipif(not SHM_PATH.is_dir(), reason='no /dev/shm on this system')
@pytest.mark.parametrize('transports', ['', 'DEFAULT'])
def test_the_node_of_a_large_scene_has_the_large_segment(monkeypatch, transports):
    """sheet_316x316 (1.6 MB clouds): the node's participant is made before the scene loads."""
    if transports:
        monkeypatch.setenv('FASTDDS_BUILTIN_TRANSPORTS', transports)
    for name in ('FASTRTPS_DEFAULT_PROFILES_FILE', 'FASTDDS_DEFAULT_PROFILES_FILE',
                 'RMW_IMPLEMENTATION') + (() if transports else ('FASTDDS_BUILTIN_TRANSPORTS',)):
        monkeypatch.delenv(name, raising=False)
    before = set(_segments())
    node = NodeProcess('scene:=sheet_316x316', 'filter.type:=lowpass', 'filter.by:=index',
                       'filter.high_mode:=7', namespace='shm' + transports.lower())
    try:
        assert wait_for(lambda: _new_segments(before), 60), node.stderr()
        time.sleep(1.0)                     # the node's participant has made all of its own
        large = [size for size in _new_segments(before).values() if size >= SEGMENT_BYTES]
        assert bool(large) == (not transports), _new_segments(before)
    finally:
        code, _, err = node.interrupt(timeout=60.0)
    assert code == 0, err[-2000:]


@pytest.mark.slow
@pytest.mark.skipif(not SHM_PATH.is_dir(), reason='no /dev/shm on this system')
def test_a_replay_of_large_clouds_has_the_large_segment(tmp_path, monkeypatch):
    """A bag of 0.6 MB clouds is played back as the node sent them: over the large segment."""
    for name in ('FASTRTPS_DEFAULT_PROFILES_FILE', 'FASTDDS_DEFAULT_PROFILES_FILE',
                 'RMW_IMPLEMENTATION', 'FASTDDS_BUILTIN_TRANSPORTS'):
        monkeypatch.delenv(name, raising=False)
    scene = scene_from_dict(hanging_sheet(200))       # 40,000 points
    bag = RunBagWriter(tmp_path / 'large', scene, None, dt=1e-3, frame_every=0, duration=0.0,
                       parameters={'scene': 'sheet_200x200'}, node='/modal_spring')
    for k in range(5):
        bag.frame(0.1 * k, scene.rest_positions)
    bag.close()
    before = set(_segments())
    player = subprocess.Popen([console_script('modal_spring_replay'), str(tmp_path / 'large'),
                               '--loop'], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True, start_new_session=True)
    try:
        assert wait_for(lambda: any(size >= SEGMENT_BYTES
                                    for size in _new_segments(before).values()), 60)
        time.sleep(1.0)                     # playing (a stop before it plays is tested too)
    finally:
        player.send_signal(signal.SIGINT)
        _, err = player.communicate(timeout=30)
    assert player.returncode == 0, err
    assert '0.6 MB clouds over shared memory (32 MB segment)' in err, err

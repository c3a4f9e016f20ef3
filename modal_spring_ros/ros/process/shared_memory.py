"""
Large clouds over shared memory: the node's Fast DDS participant gets a segment they fit in.

Fast DDS (rmw_fastrtps, ROS 2's default RMW) sends to readers on the same host through shared
memory only what fits its default 0.5 MB segment; a larger cloud (about 30,000 particles and up)
goes over UDP loopback in 64 kB fragments, which at 60 Hz costs most of the stream's latency (the
100k sheet: median 14-21 ms, against about 5 ms through a 32 MB segment; docs/speed.md). So the
node, when its scene's clouds are larger than that (read from the scene file before the middleware
starts: :func:`scene_argument`, ``scenes/files/declared_size.py``), points Fast DDS at the profile
the package ships (``config/fastdds_large_clouds.xml``: the default transports, shared memory then
UDPv4, with a 32 MB segment; Fast DDS fills the whole segment when it creates it, so smaller clouds
keep the default) unless the user chose:

- another RMW (``RMW_IMPLEMENTATION`` naming one that is not Fast DDS);
- a Fast DDS profile or transports of their own (``FASTRTPS_DEFAULT_PROFILES_FILE``,
  ``FASTDDS_DEFAULT_PROFILES_FILE``, ``FASTDDS_BUILTIN_TRANSPORTS``, or a
  ``DEFAULT_FASTRTPS_PROFILES.xml`` in the working directory, which Fast DDS loads itself);
- or the host cannot hold the segment: ``/dev/shm`` with less than :data:`SHM_FREE_NEEDED`
  free (a container's default is 64 MB).

It is safe with every ``ROS_AUTOMATIC_DISCOVERY_RANGE``: rmw_fastrtps takes the profile's
participant settings and then applies the range to discovery alone (its locators and peers),
and shared memory only ever joins participants on one host; readers elsewhere get the frames
over UDPv4 as before. Only the publisher's segment matters, so subscribers need nothing.

:func:`cloud_transport` is the sentence the node's start line gives a cloud too large for the
default segment: how it travels, and how to change that when it travels over UDP.
"""
from __future__ import annotations

import contextlib
import os
from pathlib import Path
from typing import Callable, MutableMapping

import yaml

#: the profile the package ships, relative to its share directory
PROFILE = Path('config') / 'fastdds_large_clouds.xml'
#: its shared-memory segment, bytes
SEGMENT_BYTES = 32 * 1024 * 1024
#: Fast DDS's default segment, bytes: clouds up to this size use shared memory anyway
DEFAULT_SEGMENT_BYTES = 512 * 1024
#: a streamed point (x, y, z, displacement as float32)
POINT_BYTES = 16
#: free space /dev/shm needs for the profile to be chosen (the segment, twice over)
SHM_FREE_NEEDED = 2 * SEGMENT_BYTES
#: where Linux keeps POSIX shared memory
SHM_PATH = Path('/dev/shm')
#: the RMWs that are Fast DDS (the default when ``RMW_IMPLEMENTATION`` is unset)
FAST_DDS_RMWS = ('rmw_fastrtps_cpp', 'rmw_fastrtps_dynamic_cpp')
PROFILES_VARIABLE = 'FASTRTPS_DEFAULT_PROFILES_FILE'
#: what says the user chose Fast DDS's transports themselves
USER_CHOICES = (PROFILES_VARIABLE, 'FASTDDS_DEFAULT_PROFILES_FILE', 'FASTDDS_BUILTIN_TRANSPORTS')
#: profile files Fast DDS loads from the working directory by itself
DEFAULT_PROFILE_FILES = ('DEFAULT_FASTRTPS_PROFILES.xml', 'DEFAULT_FASTDDS_PROFILES.xml')


def free_bytes(path: Path) -> int:
    """Return the bytes free on the file system of ``path`` (0 where there is none)."""
    try:
        stat = os.statvfs(path)
    except OSError:
        return 0
    return stat.f_bavail * stat.f_frsize


def user_choice(environ: MutableMapping[str, str], cwd: Path) -> str:
    """Return what already decides Fast DDS's transports ('' when nothing does)."""
    for name in USER_CHOICES:
        if environ.get(name, ''):
            return f'{name}={environ[name]}'
    for name in DEFAULT_PROFILE_FILES:
        if (cwd / name).is_file():
            return f'{cwd / name}'
    return ''


def is_fast_dds(rmw: str) -> bool:
    """Tell whether ``rmw`` (an RMW implementation's name; '' = the default) is Fast DDS."""
    return rmw in ('',) + FAST_DDS_RMWS


def scene_argument(ros_args: list[str], default: str) -> str:
    """
    Return the ``scene`` parameter a command line gives the node (``default`` when none does).

    Read before ``rclpy.init``, as rcl will: ``-p``/``--param scene:=X`` over a
    ``--params-file``'s ``scene`` (under any node's ``ros__parameters``), the last of each.
    """
    given, from_files = '', ''
    for flag, value in zip(ros_args, ros_args[1:]):
        if flag in ('-p', '--param') and value.startswith('scene:='):
            given = value[len('scene:='):]
        elif flag == '--params-file':
            with contextlib.suppress(OSError, yaml.YAMLError, AttributeError, TypeError):
                for entry in (yaml.safe_load(Path(value).read_text()) or {}).values():
                    scene = (entry.get('ros__parameters') or {}).get('scene')
                    from_files = str(scene) if scene is not None else from_files
    return given or from_files or default


def prefer_large_shared_memory(share: Path, cloud_bytes: int | None,
                               environ: MutableMapping[str, str] | None = None,
                               cwd: Path | None = None,
                               shm_free: Callable[[], int] = lambda: free_bytes(SHM_PATH)
                               ) -> bool:
    """
    Point Fast DDS at the large-segment profile where clouds need it; return whether it did.

    ``cloud_bytes``: the largest message to be published (a scene's cloud, as its size is
    declared, or a bag's; None: not known, nothing done); clouds that fit the default segment
    need nothing (the profile's segment costs its size in /dev/shm). ``share``:
    the package's share directory; ``environ``: the process environment by default (read by the
    middleware when the node is created); ``cwd``: the working directory by default.
    """
    environ = os.environ if environ is None else environ
    cwd = Path.cwd() if cwd is None else cwd
    profile = share / PROFILE
    if (cloud_bytes is None or cloud_bytes <= DEFAULT_SEGMENT_BYTES
            or not is_fast_dds(environ.get('RMW_IMPLEMENTATION', ''))
            or user_choice(environ, cwd) or not profile.is_file()
            or shm_free() < SHM_FREE_NEEDED):
        return False
    environ[PROFILES_VARIABLE] = str(profile)
    return True


def cloud_transport(cloud_bytes: int, rmw: str, share: Path,
                    environ: MutableMapping[str, str] | None = None, cwd: Path | None = None,
                    shm_free: Callable[[], int] = lambda: free_bytes(SHM_PATH)) -> str:
    """
    Return how clouds of ``cloud_bytes`` travel to readers on this host, for the start line.

    '' for clouds that fit Fast DDS's default segment, or another RMW's small ones.
    """
    if cloud_bytes <= DEFAULT_SEGMENT_BYTES:
        return ''
    environ = os.environ if environ is None else environ
    cwd = Path.cwd() if cwd is None else cwd
    size = f'{cloud_bytes / 1e6:.1f} MB clouds'
    if not is_fast_dds(rmw):
        return f'{size}: {rmw} decides their transport (see its shared-memory settings)'
    if environ.get(PROFILES_VARIABLE, '') == str(share / PROFILE):
        if cloud_bytes > SEGMENT_BYTES // 4:
            return (f'{size} over shared memory, a {SEGMENT_BYTES >> 20} MB segment holding '
                    f'{SEGMENT_BYTES // cloud_bytes} of them (a profile of your own with '
                    f'{PROFILES_VARIABLE} can give more)')
        return f'{size} over shared memory ({SEGMENT_BYTES >> 20} MB segment)'
    chosen = user_choice(environ, cwd)
    if chosen:
        return f'{size}: their transport is yours ({chosen})'
    if not (share / PROFILE).is_file():
        return f'{size} over UDP loopback: the package has no {PROFILE} (reinstall it)'
    if shm_free() >= SHM_FREE_NEEDED:   # the scene's size was not known before the node started
        return (f'{size} over UDP loopback: for shared memory start the node with '
                f'{PROFILES_VARIABLE}={share / PROFILE}')
    return (f'{size} over UDP loopback: /dev/shm has {shm_free() / 2**20:.0f} MB free, the '
            f'large-cloud segment needs {SHM_FREE_NEEDED >> 20} MB (a container: '
            '--shm-size=256m)')

"""
Write rosbag2 bags in MCAP storage, as ``ros2 bag record`` on Jazzy writes them.

A bag is a folder ``NAME/`` with ``NAME_0.mcap`` and, once closed, ``metadata.yaml``
(``rosbag2_bagfile_information``, version 9). The MCAP file has profile ``ros2``; one schema
per type (encoding ``ros2msg``, the full definition as rosbag2 concatenates it); channels with
message encoding ``cdr`` and metadata ``offered_qos_profiles`` and ``topic_type_hash``;
``rosbag2`` metadata records (one at open, one at close) holding the serialized bag
information; chunks with message indexes, and a summary with statistics.

Messages are written as serialized CDR. A message the program builds itself (a node's capture,
a re-simulation) is encoded from its schema (:mod:`~modal_spring_ros.bags.messages.cdr_encoder`):
exactly as long as its fields need (rclpy's ``serialize_message`` leaves up to 24 trailing
bytes, which rosbags refuses) and with zeroed padding (rclpy's holds whatever the buffer held),
so the same message gives the same bytes in every process. A chunk is closed when it is full or
a second old (``chunk_seconds``), and the file is flushed whenever a chunk is closed, so a
writer that is killed loses at most about the last second.
"""
from __future__ import annotations

import contextlib
import dataclasses
import functools
import json
import math
import os
from pathlib import Path
import shutil
import time
from typing import Any

from mcap.writer import CompressionType, IndexType, Writer
from modal_spring_ros import __version__
from modal_spring_ros.bags.messages.cdr_encoder import message_encoder
from modal_spring_ros.bags.messages.message_definitions import full_definition, type_hash
from modal_spring_ros.core.model.scene import Scene
from modal_spring_ros.scenes.files.scene_archive import MEDIA_TYPE, scene_to_archive
import yaml

METADATA_VERSION = 9
ROS_DISTRO = 'jazzy'
#: rosbag2's MCAP default chunk size (bytes)
DEFAULT_CHUNK_SIZE = 786_432
#: a chunk older than this (wall time, s) is closed, full or not
DEFAULT_CHUNK_SECONDS = 1.0
#: name of the attachment holding a run's scene (an archive of its arrays)
SCENE_ATTACHMENT = 'scene.npz'
#: name of the MCAP metadata record with the run's own description (scene, settings)
RUN_RECORD = 'modal_spring_ros'


@functools.lru_cache(maxsize=None)
def _encoder(type_name: str):
    return message_encoder(type_name, full_definition(type_name))


def canonical_cdr(type_name: str, msg) -> bytes:
    """
    Return ``msg`` (of ``type_name``, pkg/msg/Type) as CDR: no trailing bytes, zeroed padding.

    Deterministic: the same message gives the same bytes in every process.
    """
    return _encoder(type_name)(msg)


class BagError(ValueError):
    """A bag that cannot be written or read; the message says which and why."""


def check_new_bag_path(directory: str | Path) -> Path:
    """Return the folder a new bag may be written to; raises BagError (and touches nothing)."""
    d = Path(directory)
    too_long = _too_long(d)
    if too_long:
        raise BagError(f'{str(d)[:60]}...: {too_long} (nothing was written)')
    if d.exists():
        raise BagError(f'{d}: already exists; a bag is written to a new folder '
                       '(nothing was overwritten)')
    parent = d.parent if str(d.parent) else Path('.')
    if not parent.is_dir():
        raise BagError(f'{d}: parent folder {parent} does not exist')
    if not os.access(parent, os.W_OK):
        raise BagError(f'{d}: parent folder {parent} is not writable')
    return d


def _too_long(d: Path) -> str:
    """Say why the file system would refuse the bag's names for their length, or ''."""
    parent = d.parent if str(d.parent) else Path('.')
    try:
        name_max = os.pathconf(parent if parent.is_dir() else '.', 'PC_NAME_MAX')
        path_max = os.pathconf(parent if parent.is_dir() else '.', 'PC_PATH_MAX')
    except (OSError, ValueError):
        name_max, path_max = 255, 4096
    longest = max([len(os.fsencode(p)) for p in d.parts] + [len(os.fsencode(d.name)) + 7])
    if longest > name_max:  # the folder, or the file named after it (<name>_0.mcap)
        return (f'a name of {longest} bytes is too long for the file system (at most '
                f'{name_max})')
    if len(os.fsencode(os.path.abspath(d))) + len(d.name) + 8 > path_max:
        return f'the path is too long for the file system (at most {path_max} bytes)'
    return ''


@dataclasses.dataclass(frozen=True)
class TopicCount:
    """A topic of a bag and how many messages it holds (``metadata.yaml``'s topic entry)."""

    name: str
    type_name: str
    offered_qos_profiles: str
    type_hash: str
    count: int


def bag_information(file_names: list[str], topics: list[TopicCount], start: int | None,
                    end: int | None) -> dict[str, Any]:
    """
    Return a bag's ``rosbag2_bagfile_information`` (version 9), as rosbag2 writes it.

    ``start`` and ``end``: the first and last log times, ns (None: no message). With several
    files every message count and time span is the bag's (each file's entry alike).
    """
    begin = start if start is not None else 0
    duration = (end - begin) if end is not None else 0
    count = sum(t.count for t in topics)
    return {
        'version': METADATA_VERSION,
        'storage_identifier': 'mcap',
        'duration': {'nanoseconds': int(duration)},
        'starting_time': {'nanoseconds_since_epoch': int(begin)},
        'message_count': count,
        'topics_with_message_count': [
            {'topic_metadata': {'name': t.name, 'type': t.type_name,
                                'serialization_format': 'cdr',
                                'offered_qos_profiles': t.offered_qos_profiles,
                                'type_description_hash': t.type_hash},
             'message_count': t.count}
            for t in topics],
        'compression_format': '',
        'compression_mode': '',
        'relative_file_paths': list(file_names),
        'files': [{'path': name,
                   'starting_time': {'nanoseconds_since_epoch': int(begin)},
                   'duration': {'nanoseconds': int(duration)},
                   'message_count': count} for name in file_names],
        'custom_data': {},
        'ros_distro': ROS_DISTRO,
    }


def write_bag_information(directory: Path, info: dict[str, Any]) -> None:
    """Write ``metadata.yaml`` into a bag's folder; raises BagError."""
    try:
        (directory / 'metadata.yaml').write_text(
            yaml.safe_dump({'rosbag2_bagfile_information': info}, sort_keys=False))
    except OSError as exc:
        raise BagError(f'{directory}: cannot write metadata.yaml: '
                       f'{exc.strerror or exc}') from None


class BagWriter:
    """A rosbag2 MCAP bag being written. Use as a context manager or call :meth:`close`."""

    def __init__(self, directory: str | Path, *, chunk_size: int = DEFAULT_CHUNK_SIZE,
                 chunk_seconds: float = DEFAULT_CHUNK_SECONDS, attachments: bool = False):
        """
        Return a chunk is closed (and put on disk) by size or by age.

        A chunk is closed (and put on disk) when it holds ``chunk_size`` bytes or when it is
        ``chunk_seconds`` old, whichever comes first: a writer that is killed loses at most about
        that much. ``attachments``: the bag will hold attachments (a run record's scene,
        :meth:`add_run_record`), and their index.
        """
        if not (isinstance(chunk_size, int) and chunk_size >= 1):
            raise BagError(f'chunk size ({chunk_size}) must be a whole number of bytes, '
                           'at least 1')
        if not (math.isfinite(chunk_seconds) and chunk_seconds > 0.0):
            raise BagError(f'chunk seconds ({chunk_seconds}) must be a positive number')
        self.chunk_seconds = float(chunk_seconds)
        self._chunk_opened: float | None = None  # wall time of the open chunk's first message
        self.directory = check_new_bag_path(directory)
        try:
            self.directory.mkdir()
        except OSError as exc:
            raise BagError(f'{self.directory}: cannot create: {exc.strerror or exc}') from None
        self.file_name = f'{self.directory.name}_0.mcap'
        self._fh = open(self.directory / self.file_name, 'wb')
        # the attachments' index only where there will be attachments: an empty attachment
        # index group is a summary offset that points at nothing (mcap doctor flags it)
        self.attachments = attachments
        indexes = IndexType.ALL if attachments else IndexType.ALL & ~IndexType.ATTACHMENT
        self._writer = Writer(self._fh, chunk_size=chunk_size, compression=CompressionType.NONE,
                              index_types=indexes)
        self._writer.start(profile='ros2', library=f'modal_spring_ros {__version__}')
        self._schemas: dict[str, int] = {}
        self._topics: dict[str, dict[str, Any]] = {}
        self._start: int | None = None
        self._end: int | None = None
        self._closed = False
        #: why writing stopped ('' while it goes on)
        self.failed = ''
        self._writer.add_metadata('rosbag2', {'serialized_metadata': self._info_yaml()})
        self._fh.flush()

    # -- topics and messages -------------------------------------------------------------------
    @contextlib.contextmanager
    def _writing(self):
        """
        Write to the file; a failure stops all writing, as a BagError.

        A full disk or a device gone: the chunks already on disk stay readable, nothing more is
        written, and every later write says why.
        """
        if self.failed:
            raise BagError(f'{self.directory}: not written to any more: {self.failed}')
        try:
            yield
        except OSError as exc:
            self.failed = f'cannot write: {exc.strerror or exc}'
            raise BagError(f'{self.directory}: {self.failed}') from None

    def add_topic(self, name: str, type_name: str, offered_qos_profiles: str = '') -> None:
        """Declare a topic (type like ``sensor_msgs/msg/PointCloud2``)."""
        if name in self._topics:
            return
        with self._writing():
            self._add_topic(name, type_name, offered_qos_profiles)

    def _add_topic(self, name: str, type_name: str, offered_qos_profiles: str) -> None:
        if type_name not in self._schemas:
            self._schemas[type_name] = self._writer.register_schema(
                name=type_name, encoding='ros2msg',
                data=full_definition(type_name).encode('utf-8'))
        channel = self._writer.register_channel(
            topic=name, message_encoding='cdr', schema_id=self._schemas[type_name],
            metadata={'offered_qos_profiles': offered_qos_profiles,
                      'topic_type_hash': type_hash(type_name)})
        self._topics[name] = {'channel': channel, 'type': type_name, 'count': 0,
                              'qos': offered_qos_profiles}

    def write(self, topic: str, data: bytes, log_time_ns: int,
              publish_time_ns: int | None = None) -> None:
        """
        Write one serialized (CDR) message.

        :raises BagError: the file cannot be written (a full disk, a device gone): the chunks
            already on disk stay readable; nothing more is written.
        """
        t = self._topics[topic]
        with self._writing():
            before = self._fh.tell()
            self._writer.add_message(channel_id=t['channel'], log_time=int(log_time_ns),
                                     data=bytes(data),
                                     publish_time=int(log_time_ns if publish_time_ns is None
                                                      else publish_time_ns),
                                     sequence=t['count'])
            if self._fh.tell() != before:  # a chunk was completed: put it on disk now
                self._fh.flush()
                self._chunk_opened = None
        if self._chunk_opened is None:
            self._chunk_opened = time.monotonic()
        self.flush_if_due()
        t['count'] += 1
        self._start = log_time_ns if self._start is None else min(self._start, log_time_ns)
        self._end = log_time_ns if self._end is None else max(self._end, log_time_ns)

    def flush_if_due(self) -> None:
        """
        Close the open chunk if it is ``chunk_seconds`` old.

        Call it now and then when messages may stop coming.
        """
        if (self._chunk_opened is not None and not self._closed and not self.failed
                and time.monotonic() - self._chunk_opened >= self.chunk_seconds):
            with self._writing():
                self._writer.flush()
            self._chunk_opened = None

    def write_message(self, topic: str, msg, log_time_ns: int,
                      publish_time_ns: int | None = None) -> None:
        """Serialize ``msg`` by its topic's type (canonical CDR: see the module) and write it."""
        self.write(topic, canonical_cdr(self._topics[topic]['type'], msg), log_time_ns,
                   publish_time_ns)

    def add_run_record(self, data: dict[str, Any], scene: Scene | None = None) -> None:
        """
        Store the run's description in a ``modal_spring_ros`` metadata record.

        The description is the settings (values that are not strings are stored as JSON) and,
        when given, the ``scene``: an archive of its arrays
        (:mod:`~modal_spring_ros.scenes.files.scene_archive`) attached as :data:`SCENE_ATTACHMENT`,
        which the record's ``scene_archive`` names (a writer made with ``attachments``).
        """
        data = dict(data)
        with self._writing():
            if scene is not None:
                if not self.attachments:
                    raise BagError(f'{self.directory}: a scene needs a writer made with '
                                   'attachments')
                now = time.time_ns()
                self._writer.add_attachment(now, now, SCENE_ATTACHMENT, MEDIA_TYPE,
                                            scene_to_archive(scene))
                data['scene_archive'] = SCENE_ATTACHMENT
            self._writer.add_metadata(RUN_RECORD, {
                k: v if isinstance(v, str) else json.dumps(v) for k, v in data.items()})

    @property
    def message_count(self) -> int:
        return sum(t['count'] for t in self._topics.values())

    # -- closing -------------------------------------------------------------------------------
    def _info(self) -> dict[str, Any]:
        return bag_information(
            [self.file_name],
            [TopicCount(name, t['type'], t['qos'], type_hash(t['type']), t['count'])
             for name, t in sorted(self._topics.items())], self._start, self._end)

    def _info_yaml(self) -> str:
        return yaml.safe_dump(self._info(), sort_keys=False)

    def close(self) -> None:
        """
        Finalise the file (metadata record, summary) and write ``metadata.yaml``.

        After a failed write the file is closed as it is: its completed chunks stay readable
        (readers that scan a file without a summary read them).

        :raises BagError: finalising failed (a full disk).
        """
        if self._closed:
            return
        self._closed = True
        try:
            if not self.failed:
                self._writer.add_metadata('rosbag2',
                                          {'serialized_metadata': self._info_yaml()})
                self._writer.finish()
        except OSError as exc:
            self.failed = f'cannot write: {exc.strerror or exc}'
        finally:
            with contextlib.suppress(OSError):
                self._fh.close()
        if self.failed:
            raise BagError(f'{self.directory}: {self.failed}')
        write_bag_information(self.directory, self._info())

    def discard(self) -> None:
        """Close the file as it is and remove the bag's folder (a run that did not finish)."""
        self._closed = True
        with contextlib.suppress(OSError):
            self._fh.close()
        shutil.rmtree(self.directory, ignore_errors=True)

    def __enter__(self) -> 'BagWriter':
        return self

    def __exit__(self, *exc) -> None:
        self.close()

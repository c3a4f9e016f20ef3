"""
Read rosbag2 MCAP bags (folders or single ``.mcap`` files) as raw messages or numpy arrays.

Reads what rosbag2 writes (metadata versions up to 9, with or without ``metadata.yaml``) and
what :mod:`modal_spring_ros.bags.files.writer` writes, including a file whose writer was
killed before it was finalised (every complete chunk is read back).
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path
import struct
from typing import Any, Callable, Iterator

from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Attachment, Channel, Message, Metadata, Schema
from mcap.stream_reader import CRCValidationError, StreamReader
from mcap_ros2.decoder import DecoderFactory
from modal_spring_ros.bags.files.writer import BagError, RUN_RECORD
from modal_spring_ros.bags.messages.pointcloud import xyz
from modal_spring_ros.bags.messages.stamps import to_nanoseconds, to_seconds
from modal_spring_ros.core.model.scene import Scene
from modal_spring_ros.runs.run_memory import check_fits
from modal_spring_ros.scenes.files.scene_archive import recorded_scene
import numpy as np
import yaml

#: the type of the clouds (checked for non-finite values)
POINTCLOUD2 = 'sensor_msgs/msg/PointCloud2'


@dataclasses.dataclass
class TopicInfo:
    name: str
    type_name: str
    count: int
    offered_qos_profiles: str
    type_hash: str


@dataclasses.dataclass
class BagMessage:
    topic: str
    type_name: str
    log_time_ns: int
    publish_time_ns: int
    data: bytes
    schema: Schema | None = None     # the bag's own definition of its type


def _bag_information(meta: Path) -> dict:
    """Return the ``rosbag2_bagfile_information`` of a ``metadata.yaml``, its shape checked."""
    try:
        data = yaml.safe_load(meta.read_text(encoding='utf-8'))
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise BagError(f"{meta}: not rosbag2 metadata: {' '.join(str(exc).split())}") from None
    info = data.get('rosbag2_bagfile_information') if isinstance(data, dict) else None
    if not isinstance(info, dict):
        raise BagError(f'{meta}: not rosbag2 metadata: no rosbag2_bagfile_information mapping '
                       f'(the top level is {type(data).__name__})')
    paths = info.get('relative_file_paths', [])
    if not isinstance(paths, list) or not all(isinstance(p, str) and p for p in paths):
        raise BagError(f'{meta}: relative_file_paths must be a list of file names, got '
                       f'{paths!r:.60}')
    info['relative_file_paths'] = paths
    return info


class BagReader:
    """
    A bag opened for reading.

    :ivar path: the bag folder or file given.
    :ivar files: the MCAP files, in order.
    :ivar metadata: the ``rosbag2_bagfile_information`` mapping, or None without metadata.yaml.
    :ivar finalised: every file has its summary (False after a killed writer).
    """

    def __init__(self, path: str | Path):
        self.path = Path(path)
        if not self.path.exists():
            raise BagError(f'{self.path}: no such bag (folder or .mcap file)')
        self.metadata = None
        self._decoders: dict[tuple[str, bytes], Callable[[bytes], Any]] = {}
        if self.path.is_dir():
            meta = self.path / 'metadata.yaml'
            if meta.exists():
                info = _bag_information(meta)
                self.metadata = info
                self.files = [self.path / f for f in info['relative_file_paths']]
                if info.get('storage_identifier') != 'mcap':
                    raise BagError(f'{self.path}: storage '
                                   f"'{info.get('storage_identifier')}' is not mcap")
            else:
                self.files = sorted(self.path.glob('*.mcap'))
            if not self.files:
                raise BagError(f'{self.path}: no .mcap file in the bag')
        else:
            self.files = [self.path]
        self._scan()

    # -- reading -------------------------------------------------------------------------------
    def _scan(self) -> None:
        self.topics: dict[str, TopicInfo] = {}
        self.records: dict[str, list[dict[str, str]]] = {}
        #: the attachments' data by name (a run's scene)
        self.attachments: dict[str, bytes] = {}
        self._channel_topic: dict[int, str] = {}
        self.finalised = True
        for f in self.files:
            try:
                with open(f, 'rb') as fh:
                    reader = make_reader(fh)
                    header = reader.get_header()
                    if header.profile != 'ros2':
                        raise BagError(f"{f}: MCAP profile '{header.profile}' is not ros2")
                    summary = reader.get_summary()
                    if summary is None:
                        raise McapError('no summary')
                    counts = summary.statistics.channel_message_counts \
                        if summary.statistics else {}
                    for cid, ch in summary.channels.items():
                        self._add_topic(ch, summary.schemas.get(ch.schema_id),
                                        counts.get(cid, 0))
                    for rec in reader.iter_metadata():
                        self.records.setdefault(rec.name, []).append(dict(rec.metadata))
                    for rec in reader.iter_attachments():
                        self.attachments[rec.name] = bytes(rec.data)
            except BagError:
                raise
            except Exception:  # not finalised (or damaged): stream what is there
                self.finalised = False
                self._scan_stream(f)

    def _scan_stream(self, f: Path) -> None:
        schemas: dict[int, Schema] = {}
        records = 0
        try:
            with open(f, 'rb') as fh:
                for rec in StreamReader(fh, skip_magic=False).records:
                    records += 1
                    if isinstance(rec, Schema):
                        schemas[rec.id] = rec
                    elif isinstance(rec, Channel):
                        self._add_topic(rec, schemas.get(rec.schema_id), 0)
                    elif isinstance(rec, Message):
                        topic = self._channel_topic.get(rec.channel_id)
                        if topic in self.topics:
                            self.topics[topic].count += 1
                    elif isinstance(rec, Metadata):
                        self.records.setdefault(rec.name, []).append(dict(rec.metadata))
                    elif isinstance(rec, Attachment):
                        self.attachments[rec.name] = bytes(rec.data)
        except Exception as exc:
            if self.topics:
                return  # the truncated tail of a killed writer's last chunk
            if records:  # a good start, cut before its first chunk
                raise BagError(f'{f}: empty: the recording stopped before its first chunk was '
                               'written (no message is on disk)') from None
            raise BagError(f'{f}: not a readable MCAP file: '
                           f'{str(exc) or type(exc).__name__}') from None
        if not self.topics:
            raise BagError(f'{f}: empty: no topic and no message')

    def _add_topic(self, ch, schema, count: int) -> None:
        self._channel_topic[ch.id] = ch.topic
        if ch.topic in self.topics:
            self.topics[ch.topic].count += count
            return
        self.topics[ch.topic] = TopicInfo(
            name=ch.topic, type_name=schema.name if schema else '', count=count,
            offered_qos_profiles=ch.metadata.get('offered_qos_profiles', ''),
            type_hash=ch.metadata.get('topic_type_hash', ''))

    def messages(self, topics: list[str] | None = None) -> Iterator[BagMessage]:
        """Raw messages in log-time order (file order for an unfinalised file)."""
        wanted = set(topics) if topics else None
        for f in self.files:
            with open(f, 'rb') as fh:
                if not self.finalised:
                    yield from self._stream_messages(fh, wanted)
                    continue
                try:
                    it = make_reader(fh, validate_crcs=True).iter_messages(
                        topics=list(wanted) if wanted else None)
                    for schema, channel, msg in it:
                        yield BagMessage(channel.topic, schema.name if schema else '',
                                         msg.log_time, msg.publish_time, msg.data, schema)
                except CRCValidationError as exc:
                    raise BagError(f"{f}: damaged: a chunk's checksum does not match its "
                                   f'bytes ({exc})') from None
                except (McapError, ValueError, EOFError, struct.error) as exc:
                    raise BagError(f'{f}: damaged: {str(exc) or type(exc).__name__}') from None

    def check(self, topics: list[str] | None = None) -> int:
        """
        Decode every message of ``topics`` (or all) and check every cloud for non-finite values.

        Returns how many there are.

        :raises BagError: a message is damaged (named by topic and log time) or there is none.
        """
        count = 0
        for m in self.messages(topics):
            msg = self.decode(m)
            if m.type_name == POINTCLOUD2 and not np.isfinite(xyz(msg)).all():
                raise BagError(f'{self.path}: message on {m.topic} at log time '
                               f'{m.log_time_ns} ns is damaged: its cloud holds non-finite '
                               'values')
            count += 1
        if count == 0:
            raise BagError(f"{self.path}: no message on {', '.join(topics or self.topics)}")
        return count

    def _stream_messages(self, fh, wanted) -> Iterator[BagMessage]:
        schemas, channels = {}, {}
        try:
            for rec in StreamReader(fh, skip_magic=False, validate_crcs=True).records:
                if isinstance(rec, Schema):
                    schemas[rec.id] = rec
                elif isinstance(rec, Channel):
                    channels[rec.id] = rec
                elif isinstance(rec, Message):
                    ch = channels.get(rec.channel_id)
                    if ch is None or (wanted and ch.topic not in wanted):
                        continue
                    schema = schemas.get(ch.schema_id)
                    yield BagMessage(ch.topic, schema.name if schema else '', rec.log_time,
                                     rec.publish_time, rec.data, schema)
        except CRCValidationError as exc:
            raise BagError(f"{self.path}: damaged: a chunk's checksum does not match its bytes "
                           f'({exc})') from None
        except Exception:
            return  # the truncated tail of a killed writer's last chunk

    def decode(self, message: BagMessage):
        """
        Return the message decoded from the bag's own schema of its type (no ROS needed).

        mcap-ros2-support's CDR decoder reads the ``ros2msg`` definition the bag carries: a
        plain object with the message's fields (``msg.header.stamp.sec``, ``msg.data`` as
        bytes), whatever is installed; nothing a bag says is imported. The ROS tools that
        need rclpy's own classes decode through
        :func:`~modal_spring_ros.ros.tools.installed_messages.installed_message`.

        :raises BagError: the bag has no usable definition of its type, or its bytes are not
            a valid message of it.
        """
        schema = message.schema
        if schema is None or schema.encoding != 'ros2msg':
            raise BagError(f'{self.path}: message on {message.topic}: its type '
                           f'{message.type_name!r} has no ros2msg definition in the bag')
        key = (schema.name, bytes(schema.data))     # schema ids are per file
        try:
            decoder = self._decoders.get(key)
            if decoder is None:
                # a factory per definition: the factory keeps its decoders by schema id
                decoder = DecoderFactory().decoder_for('cdr', schema)
                if decoder is None:
                    raise ValueError('no CDR decoder for it')
                self._decoders[key] = decoder
            return decoder(message.data)
        except Exception as exc:  # mcap_ros2 raises several kinds for damaged definitions or CDR
            raise BagError(f'{self.path}: message on {message.topic} at log time '
                           f'{message.log_time_ns} ns is damaged: cannot decode it as '
                           f'{message.type_name} ({type(exc).__name__}: {exc})') from None

    # -- the run's own description -------------------------------------------------------------
    def run_record(self) -> dict:
        """Return the ``modal_spring_ros`` record (JSON values decoded), or {} when absent."""
        merged: dict = {}
        for rec in self.records.get(RUN_RECORD, []):
            for k, v in rec.items():
                try:
                    merged[k] = json.loads(v)
                except ValueError:
                    merged[k] = v
        return merged

    def scene(self) -> Scene | None:
        """
        Return the scene the run record holds, or None (a bag not written by this project).

        Its archive (:data:`~modal_spring_ros.bags.files.writer.SCENE_ATTACHMENT`), or the YAML
        text of bags written before scenes were archived.

        :raises SceneError: a scene the scene checks refuse; BagError: an archive named and
            missing.
        """
        rec = self.run_record()
        name = str(rec.get('scene_archive', ''))
        if name and name not in self.attachments:
            raise BagError(f"{self.path}: the run record's scene {name!r} is not attached "
                           '(a bag cut short?)')
        return recorded_scene(self.attachments.get(name) if name else None,
                              str(rec['scene_yaml']) if 'scene_yaml' in rec else None,
                              f'{self.path} (scene)')

    def points(self, topic: str = '/points', times: dict[int, float] | None = None,
               max_bytes: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """
        Return (F,) header stamps in seconds and (F, n, 3) float64 positions of a cloud topic.

        With ``times`` ({stamp ns: time s}, ``bags/files/sim_time.py``) each frame's stamp is
        replaced by its time there, and frames it lacks are left out. With ``max_bytes``, the
        positions may take that much at most: a topic whose message count says it holds more,
        or whose frames pass it as they are read, is refused
        (:class:`~modal_spring_ros.runs.run_memory.RunTooLarge`).
        """
        if topic not in self.topics:
            raise BagError(f'{self.path}: no topic {topic} (topics: '
                           f"{', '.join(sorted(self.topics)) or 'none'})")
        if self.topics[topic].type_name != POINTCLOUD2:
            raise BagError(f'{self.path}: topic {topic} holds '
                           f'{self.topics[topic].type_name or "an unnamed type"}, not '
                           f'{POINTCLOUD2}')
        stamps, frames = [], []
        for m in self.messages([topic]):
            msg = self.decode(m)
            ns = to_nanoseconds(msg.header.stamp)
            if times is not None and ns not in times:
                continue
            cloud = xyz(msg)
            if max_bytes is not None:
                held = max(self.topics[topic].count, len(frames) + 1)
                check_fits(held * cloud.nbytes, f'{self.path} ({topic})', held, len(cloud),
                           max_bytes)
            if not np.isfinite(cloud).all():
                raise BagError(f'{self.path}: message on {topic} at log time '
                               f'{m.log_time_ns} ns is damaged: its cloud holds non-finite '
                               'values')
            stamps.append(times[ns] if times is not None else to_seconds(msg.header.stamp))
            frames.append(cloud)
        if not frames:
            raise BagError(f'{self.path}: topic {topic} has no messages')
        if len({f.shape for f in frames}) > 1:
            raise BagError(f'{self.path}: the clouds on {topic} differ in size')
        return np.array(stamps), np.array(frames)

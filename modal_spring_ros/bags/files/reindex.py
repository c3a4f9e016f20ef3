"""
Make a killed recording whole again, as ``ros2 bag reindex`` does for rosbag2.

A writer killed before it closed (SIGKILL, a power cut, an out-of-memory kill) leaves its MCAP
file without a summary and footer, and its bag folder without ``metadata.yaml``. The project's
reader streams such a file, but indexed readers (mcap's ``make_reader``, rosbags, rosbag2's
``ros2 bag info``) refuse it. Reindexing reads every complete record in file order and writes
the file again, finalised: the same header, schemas, channels, messages (log and publish
times, sequence numbers, bytes), metadata records and attachments, with chunk and message
indexes, statistics and a summary, and a closing ``rosbag2`` metadata record with the bag's
information, as a closing writer adds. Then ``metadata.yaml`` is written. The incomplete tail a
killed writer leaves (its last, half-written chunk) is what is lost; it was never readable.

Nothing is imported or decoded: records are copied as bytes, so a bag of message types not
installed here reindexes too. A file that is already finalised is left as it is (its folder
gets the ``metadata.yaml`` it lacks). The new file is written beside the old one and renamed
over it: a reindex that is itself interrupted leaves the recording as it was.
"""
from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import BinaryIO, Iterator

from mcap.reader import make_reader
from mcap.records import Attachment, Channel, Header, Message, Metadata, Schema
from mcap.stream_reader import CRCValidationError, StreamReader
from mcap.writer import CompressionType, IndexType, Writer
from modal_spring_ros.bags.files.writer import (bag_information, BagError, TopicCount,
                                                write_bag_information)
import yaml

#: the metadata record rosbag2 writes at open and at close (the bag's information as YAML)
ROSBAG2_RECORD = 'rosbag2'


@dataclasses.dataclass
class FileReport:
    """What reindexing did to one MCAP file."""

    name: str
    messages: int               # messages in the file (after reindexing)
    topics: int
    rewritten: bool             # False: it was finalised already, left as it was
    stopped: str = ''           # why reading stopped before the end ('' : it did not)

    def describe(self) -> str:
        what = (f'{self.messages} messages on {self.topics} topics, '
                + ('finalised' if self.rewritten else 'already finalised, left as it was'))
        return what + (f'; read up to where {self.stopped}' if self.stopped else '')


@dataclasses.dataclass
class _Scan:
    """One pass over a file's complete records: its topics, counts and times."""

    topics: dict[int, TopicCount] = dataclasses.field(default_factory=dict)
    start: int | None = None
    end: int | None = None
    attachments: bool = False
    stopped: str = ''         # why reading stopped before the end, for a person
    cause: str = ''           # the reader's own words

    def add_message(self, msg: Message) -> None:
        topic = self.topics.get(msg.channel_id)
        if topic is not None:
            self.topics[msg.channel_id] = dataclasses.replace(topic, count=topic.count + 1)
        self.start = msg.log_time if self.start is None else min(self.start, msg.log_time)
        self.end = msg.log_time if self.end is None else max(self.end, msg.log_time)


def reindex(path: str | Path) -> list[FileReport]:
    """
    Finalise every MCAP file of the bag at ``path`` (a bag folder or one ``.mcap`` file).

    A folder also gets its ``metadata.yaml`` (written again from what the files hold).

    :raises BagError: no MCAP file, a file that is not MCAP at all, or one that cannot be
        written (the file is then as it was).
    """
    p = Path(path)
    if p.is_dir():
        files = sorted(f for f in p.glob('*.mcap') if f.is_file())
        if not files:
            raise BagError(f'{p}: no .mcap file in the bag')
    elif p.is_file():
        files = [p]
    else:
        raise BagError(f'{p}: no such bag (a folder or an .mcap file)')
    reports, scans = [], []
    for f in files:
        scan, finalised = _finalised(f)
        if scan is None:
            scan = _scan(f)
            _rewrite(f, scan)
        scans.append(scan)
        reports.append(FileReport(f.name, sum(t.count for t in scan.topics.values()),
                                  len({t.name for t in scan.topics.values()}),
                                  not finalised, scan.stopped))
    if p.is_dir():
        write_bag_information(p, _information([f.name for f in files], scans))
    return reports


def _information(names: list[str], scans: list[_Scan]) -> dict:
    topics: dict[str, TopicCount] = {}
    for scan in scans:
        for t in scan.topics.values():
            old = topics.get(t.name)
            topics[t.name] = t if old is None else dataclasses.replace(
                old, count=old.count + t.count)
    starts = [s.start for s in scans if s.start is not None]
    ends = [s.end for s in scans if s.end is not None]
    return bag_information(names, [topics[k] for k in sorted(topics)],
                           min(starts) if starts else None, max(ends) if ends else None)


def _topic(channel: Channel, schema: Schema | None) -> TopicCount:
    return TopicCount(channel.topic, schema.name if schema else '',
                      channel.metadata.get('offered_qos_profiles', ''),
                      channel.metadata.get('topic_type_hash', ''), 0)


def _finalised(f: Path) -> tuple[_Scan | None, bool]:
    """Return the scan of a finalised file from its summary (None, False: not finalised)."""
    try:
        with open(f, 'rb') as fh:
            summary = make_reader(fh).get_summary()
    except Exception:  # no footer, or one that points at nothing: not finalised
        return None, False
    if summary is None or summary.statistics is None:
        return None, False
    stats = summary.statistics
    scan = _Scan(attachments=stats.attachment_count > 0)
    for cid, ch in summary.channels.items():
        scan.topics[cid] = dataclasses.replace(
            _topic(ch, summary.schemas.get(ch.schema_id)),
            count=stats.channel_message_counts.get(cid, 0))
    if stats.message_count:
        scan.start, scan.end = stats.message_start_time, stats.message_end_time
    return scan, True


def _records(fh: BinaryIO, scan: _Scan) -> Iterator:
    """Yield a file's complete records; where they stop, say why in ``scan.stopped``."""
    try:
        yield from StreamReader(fh, skip_magic=False, validate_crcs=True).records
    except CRCValidationError as exc:
        scan.cause = str(exc)
        scan.stopped = f"a chunk's checksum does not match its bytes ({exc})"
    except Exception as exc:  # the truncated tail of a killed writer
        scan.cause = str(exc) or type(exc).__name__
        scan.stopped = ('the file ends before its footer: its writer was stopped, and what '
                        f'was not yet in a complete chunk never reached the disk ({scan.cause})')


def _scan(f: Path) -> _Scan:
    scan = _Scan()
    schemas: dict[int, Schema] = {}
    first = True
    with open(f, 'rb') as fh:
        for rec in _records(fh, scan):
            if first and not isinstance(rec, Header):
                break
            first = False
            if isinstance(rec, Schema):
                schemas[rec.id] = rec
            elif isinstance(rec, Channel) and rec.id not in scan.topics:  # (a summary repeats it)
                scan.topics[rec.id] = _topic(rec, schemas.get(rec.schema_id))
            elif isinstance(rec, Message):
                scan.add_message(rec)
            elif isinstance(rec, Attachment):
                scan.attachments = True
    if first:
        raise BagError(f'{f}: not an MCAP file: {scan.cause or "no header record"}')
    return scan


def _rewrite(f: Path, scan: _Scan) -> None:
    """Write ``f`` again from its complete records, finalised, and rename it into place."""
    new = f.with_name(f.name + '.reindexing')
    try:
        with open(f, 'rb') as src, open(new, 'wb') as out:
            _copy(src, out, scan, f.name)
            out.flush()
            os.fsync(out.fileno())
        os.replace(new, f)
    except OSError as exc:
        new.unlink(missing_ok=True)
        raise BagError(f'{f}: cannot write the reindexed file: {exc.strerror or exc} '
                       '(the recording is as it was)') from None


def _copy(src: BinaryIO, out: BinaryIO, scan: _Scan, name: str) -> None:
    """
    Copy ``src``'s complete records to a new finalised MCAP file ``out``.

    rosbag2 writes the bag's information at open and again at close: the open record is kept,
    a closing one (if the writer got that far) is written anew with the counts found.
    """
    indexes = IndexType.ALL if scan.attachments else IndexType.ALL & ~IndexType.ATTACHMENT
    writer = Writer(out, compression=CompressionType.NONE, index_types=indexes)
    schema_ids: dict[int, int] = {}
    channel_ids: dict[int, int] = {}
    started = opened = False
    ignored = _Scan()         # the first pass said where the records stop
    for rec in _records(src, ignored):
        if isinstance(rec, Header):
            writer.start(profile=rec.profile, library=rec.library)
            started = True
        elif not started:
            break
        elif isinstance(rec, Schema) and rec.id not in schema_ids:     # (a summary repeats
            schema_ids[rec.id] = writer.register_schema(rec.name, rec.encoding, rec.data)
        elif isinstance(rec, Channel) and rec.id not in channel_ids:   # schemas and channels)
            channel_ids[rec.id] = writer.register_channel(
                rec.topic, rec.message_encoding, schema_ids.get(rec.schema_id, 0),
                dict(rec.metadata))
        elif isinstance(rec, Message) and rec.channel_id in channel_ids:
            writer.add_message(channel_ids[rec.channel_id], rec.log_time, rec.data,
                               rec.publish_time, rec.sequence)
        elif isinstance(rec, Metadata):
            if rec.name != ROSBAG2_RECORD or not opened:
                writer.add_metadata(rec.name, dict(rec.metadata))
            opened = opened or rec.name == ROSBAG2_RECORD
        elif isinstance(rec, Attachment):
            writer.add_attachment(rec.create_time, rec.log_time, rec.name, rec.media_type,
                                  rec.data)
    info = _information([name], [scan])
    writer.add_metadata(ROSBAG2_RECORD, {'serialized_metadata': yaml.safe_dump(
        info, sort_keys=False)})
    writer.finish()

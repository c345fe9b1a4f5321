"""Read rosbag2 MCAP bags (a bag directory or a single ``.mcap``) for ``bag info`` and replay.

Every problem with the input surfaces as :class:`BagError` with a one-line message.
"""
from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from typing import Any, Iterable, Iterator

from rigid_body_sim.bag import metadata as md
from rigid_body_sim.bag.errors import BagError, recover_hint  # noqa: F401 (re-exported)
from rigid_body_sim.bag.writer import RUN_CONFIGURATION, decode_run_configuration

MAGIC = b'\x89MCAP0\r\n'


@dataclass
class TopicInfo:
    name: str
    type: str
    count: int = 0
    offered_qos_profiles: str = ''
    type_hash: str = ''


@dataclass
class FileInfo:
    path: str
    size: int
    count: int
    start_ns: int
    end_ns: int


@dataclass
class BagInfo:
    path: str
    files: list[FileInfo] = field(default_factory=list)
    topics: dict[str, TopicInfo] = field(default_factory=dict)
    run_configuration: dict[str, Any] | None = None
    library: str = ''

    @property
    def message_count(self) -> int:
        return sum(f.count for f in self.files)

    @property
    def start_ns(self) -> int:
        return min((f.start_ns for f in self.files if f.count), default=0)

    @property
    def end_ns(self) -> int:
        return max((f.end_ns for f in self.files if f.count), default=0)

    @property
    def duration_s(self) -> float:
        return (self.end_ns - self.start_ns) / 1e9


def bag_files(path: str) -> list[str]:
    """The ``.mcap`` files of a bag directory (metadata.yaml order, else ``_N`` order), or
    ``[path]`` for a single file."""
    if not os.path.exists(path):
        raise BagError(f'{path}: no such file or directory')
    if os.path.isfile(path):
        return [path]
    try:
        meta = md.read_metadata_yaml(path)
    except (OSError, ValueError) as exc:
        raise BagError(f'{path}: unreadable metadata.yaml ({exc})') from exc
    if meta is not None:
        if meta.get('storage_identifier', 'mcap') != 'mcap':
            raise BagError(f'{path}: storage {meta.get("storage_identifier")!r} is not mcap')
        files = [os.path.join(path, p) for p in meta.get('relative_file_paths') or []]
        missing = [f for f in files if not os.path.isfile(f)]
        if missing:
            raise BagError(f'{path}: file listed in metadata.yaml is missing: {missing[0]}')
        if files:
            return files

    def index(name: str) -> tuple[int, str]:
        m = re.search(r'_(\d+)\.mcap$', name)
        return (int(m.group(1)) if m else -1, name)

    files = sorted((f for f in os.listdir(path) if f.endswith('.mcap')), key=index)
    if not files:
        raise BagError(f'{path}: no .mcap files in this directory')
    return [os.path.join(path, f) for f in files]


def is_finished(path: str) -> bool:
    """True when the file ends with the MCAP footer magic (its writer called finish())."""
    try:
        with open(path, 'rb') as f:
            if f.read(8) != MAGIC:
                return False
            f.seek(0, os.SEEK_END)
            if f.tell() < 16:
                return False
            f.seek(-8, os.SEEK_END)
            return f.read(8) == MAGIC
    except OSError:
        return False


def check_file(path: str, bag: str | None = None) -> None:
    """Raise BagError unless ``path`` is a finished ROS 2 MCAP file (of bag ``bag``)."""
    try:
        with open(path, 'rb') as f:
            head = f.read(8)
    except OSError as exc:
        raise BagError(f'{path}: cannot read ({exc.strerror})') from exc
    if head != MAGIC:
        raise BagError(f'{path}: not an MCAP file')
    if not is_finished(path):
        raise BagError(f'{path}: unfinished or truncated MCAP file (no summary/footer); '
                       f'recover it with: {recover_hint(bag or path)}')


def _open(path: str, bag: str | None = None) -> tuple[Any, Any]:
    from mcap.reader import make_reader
    check_file(path, bag if bag and os.path.isdir(bag) else None)
    stream = open(path, 'rb')
    try:
        reader = make_reader(stream)
        header = reader.get_header()
        if header.profile != 'ros2':
            raise BagError(f'{path}: MCAP profile is {header.profile!r}, not "ros2" '
                           '(not a ROS 2 bag)')
        return stream, reader
    except BagError:
        stream.close()
        raise
    except Exception as exc:  # mcap raises many types for corrupt input
        stream.close()
        raise BagError(f'{path}: corrupt MCAP file ({type(exc).__name__}: {exc})') from exc


def read_info(path: str) -> BagInfo:
    """Topics, types, counts, times and run configuration of a bag (from the summaries)."""
    info = BagInfo(path)
    for file in bag_files(path):
        stream, reader = _open(file, path)
        try:
            with stream:
                summary = reader.get_summary()
                if summary is None or summary.statistics is None:
                    raise BagError(f'{file}: MCAP file has no summary statistics; '
                                   f'rewrite it with: {recover_hint(file)}')
                info.library = reader.get_header().library
                stats = summary.statistics
                for cid, channel in summary.channels.items():
                    schema = summary.schemas.get(channel.schema_id)
                    if channel.message_encoding != 'cdr' or schema is None:
                        raise BagError(f'{file}: topic {channel.topic} is not a ROS 2 (cdr) '
                                       'topic')
                    topic = info.topics.setdefault(channel.topic, TopicInfo(
                        channel.topic, schema.name,
                        offered_qos_profiles=channel.metadata.get('offered_qos_profiles', ''),
                        type_hash=channel.metadata.get('topic_type_hash', '')))
                    topic.count += stats.channel_message_counts.get(cid, 0)
                count = stats.message_count
                info.files.append(FileInfo(file, os.path.getsize(file), count,
                                           stats.message_start_time if count else 0,
                                           stats.message_end_time if count else 0))
                for record in reader.iter_metadata():
                    if record.name == RUN_CONFIGURATION:
                        info.run_configuration = decode_run_configuration(record.metadata)
        except BagError:
            raise
        except Exception as exc:
            raise BagError(f'{file}: corrupt MCAP file ({type(exc).__name__}: {exc})') from exc
    return info


@dataclass
class Message:
    topic: str
    type: str
    data: bytes
    log_time_ns: int
    publish_time_ns: int


def iter_messages(path: str, topics: Iterable[str] | None = None,
                  start_ns: int | None = None) -> Iterator[Message]:
    """Serialized messages of the bag in log-time order (files are consecutive in time)."""
    wanted = list(topics) if topics is not None else None
    for file in bag_files(path):
        stream, reader = _open(file, path)
        with stream:
            try:
                for schema, channel, msg in reader.iter_messages(
                        topics=wanted, start_time=start_ns, log_time_order=True):
                    yield Message(channel.topic, schema.name if schema else '', msg.data,
                                  msg.log_time, msg.publish_time)
            except BagError:
                raise
            except Exception as exc:
                raise BagError(f'{file}: corrupt MCAP file '
                               f'({type(exc).__name__}: {exc})') from exc

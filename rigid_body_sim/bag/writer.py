"""BagWriter: serialized ROS 2 messages -> a rosbag2 (Jazzy) MCAP bag directory.

Layout and records follow rosbag2_storage_mcap: ``<dir>/<name>_<n>.mcap`` with profile
``ros2``, one ``ros2msg`` schema per type, ``cdr`` channels carrying
``offered_qos_profiles``/``topic_type_hash``, plus a version-9 ``metadata.yaml``.

Crash safety: chunks are zstd-compressed and flushed to the OS at least every
``flush_period`` seconds, so a SIGKILL loses at most that much; ``bag recover`` rebuilds
the index of such a file. Not thread-safe: call it from one thread (the executor's).
"""
from __future__ import annotations

import functools
import json
import os
import subprocess
import time
from typing import Any, BinaryIO

from mcap.data_stream import RecordBuilder
from mcap.writer import CompressionType, Writer

import rigid_body_sim
from rigid_body_sim.bag import metadata as md
from rigid_body_sim.bag.errors import recover_hint
from rigid_body_sim.bag.errors import BagError
from rigid_body_sim.bag.schema import DEFAULT_QOS_YAML, TypeNotFound, message_definition
from rigid_body_sim.bag.schema import type_hash as installed_type_hash
from rigid_body_sim.param_spec import check_output_path

RUN_CONFIGURATION = 'rigid_body_sim/run_configuration'
CHUNK_SIZE = 768 * 1024      # rosbag2's default (mcap DefaultChunkSize)
_COMPRESSION = {'zstd': CompressionType.ZSTD, 'lz4': CompressionType.LZ4,
                'none': CompressionType.NONE, '': CompressionType.NONE}


def library_string() -> str:
    import mcap
    return f'rigid_body_sim/{rigid_body_sim.__version__}; mcap-python/{mcap.__version__}'


@functools.lru_cache(maxsize=1)
def git_revision() -> str | None:
    """The source checkout's commit (``+dirty`` when modified), or None outside a checkout."""
    src = os.path.dirname(os.path.dirname(os.path.abspath(rigid_body_sim.__file__)))
    try:
        rev = subprocess.run(['git', '-C', src, 'rev-parse', 'HEAD'], capture_output=True,
                             text=True, timeout=2, check=True).stdout.strip()
        # --no-optional-locks: status refreshes the index under .git/index.lock, and a git
        # killed meanwhile (the timeout; a recorder's process group SIGKILLed) left that
        # lock in the user's checkout: every later git command there failed (a loaded
        # make test once left one)
        dirty = subprocess.run(['git', '--no-optional-locks', '-C', src, 'status',
                                '--porcelain', '-uno'],
                               capture_output=True, text=True, timeout=2).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return rev + ('+dirty' if dirty else '') if rev else None


def encode_run_configuration(config: dict[str, Any]) -> dict[str, str]:
    """MCAP metadata values are strings: every top-level value is stored as JSON."""
    return {str(k): json.dumps(v, sort_keys=True, default=str) for k, v in config.items()}


def decode_run_configuration(record: dict[str, str]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in record.items():
        try:
            out[key] = json.loads(value)
        except ValueError:
            out[key] = value
    return out


class _PackedChunkIndexes:
    """The ChunkIndex records written so far, held as one run of their bytes until the
    summary is written.

    The mcap Writer keeps one ChunkIndex per chunk until ``finish`` (the summary lists
    them). As a dataclass with a dict of per-channel offsets each takes ~1.5 kB; a recorder
    flushing every second writes 3,600 chunks an hour, so the recorder grew ~5 MB/h. As
    bytes a record is ~220 B with a dozen topics (0.8 MB/h), and the file written is byte
    for byte the same. Stands first in the Writer's list; the Writer writes it as one."""
    __slots__ = ('records', 'count')

    def __init__(self):
        self.records = bytearray()
        self.count = 0

    def add(self, index) -> None:
        builder = RecordBuilder()
        index.write(builder)
        self.records += builder.end()
        self.count += 1

    def write(self, stream: RecordBuilder) -> None:
        stream.write(self.records)


class _File:
    """One open ``.mcap`` of the bag with its own schema/channel ids and statistics."""

    def __init__(self, path: str, relpath: str, compression: CompressionType, chunk_size: int):
        self.stream: BinaryIO = open(path, 'xb')
        self.mcap = Writer(self.stream, chunk_size=chunk_size, compression=compression)
        self.mcap.start(profile='ros2', library=library_string())
        self.stats = md.FileStats(relpath)
        self.schemas: dict[str, int] = {}
        self.channels: dict[str, int] = {}
        # the Writer's list of chunk indexes (mcap 1.6, pinned): packed after each flush
        self._indexes = getattr(self.mcap, '_Writer__chunk_indices', None)
        self._packed = _PackedChunkIndexes()

    def pack_chunk_indexes(self) -> None:
        """Hold the chunk indexes written so far as bytes (see _PackedChunkIndexes)."""
        if self._indexes is None:  # another mcap version: nothing packed, nothing lost
            return
        new = [i for i in self._indexes if i is not self._packed]
        for index in new:
            self._packed.add(index)
        self._indexes[:] = [self._packed]


class BagWriter:
    """Write a rosbag2-compatible MCAP bag from serialized (CDR) messages.

    ``directory`` is created and must not already hold a bag. Files are named
    ``<name>_0.mcap``, ``<name>_1.mcap``, ... (``name`` defaults to the directory's
    basename) and split when ``max_bag_duration`` (s, log time) or ``max_bag_size``
    (bytes) is exceeded; 0 disables a limit.
    """

    def __init__(self, directory: str, *, name: str | None = None,
                 max_bag_duration: float = 0.0, max_bag_size: int = 0,
                 flush_period: float = 1.0, compression: str = 'zstd',
                 chunk_size: int = CHUNK_SIZE, fsync: bool = False) -> None:
        if compression not in _COMPRESSION:
            raise BagError(f'unknown compression {compression!r} (use zstd, lz4 or none)')
        try:
            check_output_path(directory, 'output directory')
        except ValueError as exc:
            raise BagError(str(exc)) from None
        self.directory = os.path.abspath(directory)
        if os.path.isdir(self.directory) and os.listdir(self.directory):
            raise BagError(f'output directory {directory} already exists and is not empty')
        try:
            os.makedirs(self.directory, exist_ok=True)
        except OSError as exc:
            raise BagError(f'cannot create output directory {directory}: {exc.strerror}') from exc
        self.name = name or os.path.basename(self.directory.rstrip(os.sep)) or 'bag'
        self.max_bag_duration_ns = int(max_bag_duration * 1e9)
        self.max_bag_size = int(max_bag_size)
        self.flush_period = float(flush_period)
        self.fsync = fsync
        self._compression = _COMPRESSION[compression]
        self._chunk_size = chunk_size
        self._topics: dict[str, md.TopicStats] = {}
        self._files: list[md.FileStats] = []
        self._run_configuration: dict[str, str] | None = None
        self._file: _File | None = None
        self._last_flush = time.monotonic()
        self._since_size_check = 0
        self._broken: str | None = None  # set by a failed write (disk full, size limit)
        self._open_next()

    # --- public API ------------------------------------------------------------------

    @property
    def paths(self) -> list[str]:
        """Absolute paths of the files written so far (the last one may be open)."""
        return [os.path.join(self.directory, f.path) for f in self._files]

    @property
    def message_count(self) -> int:
        return sum(f.count for f in self._files)

    def topic_counts(self) -> dict[str, int]:
        return {t.name: t.count for t in self._topics.values()}

    def has_topic(self, topic: str) -> bool:
        return topic in self._topics

    def add_topic(self, topic: str, type_name: str,
                  offered_qos_profiles: str = DEFAULT_QOS_YAML,
                  type_hash: str | None = None) -> None:
        """Declare ``topic`` (``pkg/msg/Type``); its definition is read from the installed
        interface files. ``offered_qos_profiles`` is rosbag2's v9 QoS YAML string."""
        if topic in self._topics:
            if self._topics[topic].type != type_name:
                raise BagError(f'topic {topic} already recorded as {self._topics[topic].type}')
            return
        try:
            message_definition(type_name)
        except TypeNotFound as exc:
            raise BagError(f'cannot record {topic}: {exc}') from exc
        if type_hash is None:
            type_hash = installed_type_hash(type_name)
        self._topics[topic] = md.TopicStats(topic, type_name, offered_qos_profiles, type_hash)
        self._register(self._file, topic)

    def _failed(self, exc: OSError) -> BagError:
        """A write failed (disk full, file size limit, I/O error): stop writing; the
        chunks already on disk stay recoverable (``bag recover``)."""
        path = os.path.join(self.directory, self._file.stats.path) if self._file else \
            self.directory
        self._broken = path
        return BagError(f'cannot write {path}: {exc.strerror or exc} (errno {exc.errno}); '
                        f'recording stopped after {self.message_count} messages')

    def write(self, topic: str, data: bytes, log_time_ns: int,
              publish_time_ns: int | None = None) -> None:
        """Append one serialized message; ``log_time_ns`` is the receive time (ns).
        BagError naming the file if the disk refuses the data (then nothing more is
        written)."""
        try:
            self._write(topic, data, log_time_ns, publish_time_ns)
        except OSError as exc:
            raise self._failed(exc) from None

    def _write(self, topic, data, log_time_ns, publish_time_ns) -> None:
        if self._broken:
            raise BagError(f'{self._broken}: the bag stopped after a write error')
        f = self._file
        if f is None:
            raise BagError('bag writer is closed')
        if self.max_bag_duration_ns and f.stats.count and \
                log_time_ns - f.stats.start_ns >= self.max_bag_duration_ns:
            f = self._split()
        channel = f.channels.get(topic)
        if channel is None:
            raise BagError(f'topic {topic} was not added to the bag')
        f.stats.add(topic, log_time_ns)
        self._topics[topic].count += 1
        f.mcap.add_message(channel, log_time_ns, data,
                           publish_time_ns if publish_time_ns else log_time_ns,
                           self._topics[topic].count)
        self._since_size_check += 1
        if self.max_bag_size and self._since_size_check >= 64:
            self._since_size_check = 0
            if f.stream.tell() >= self.max_bag_size:
                self._split()
        if time.monotonic() - self._last_flush >= self.flush_period:
            self.flush()

    def flush(self) -> None:
        """Close the current chunk and hand it to the OS (fsync too when ``fsync=True``)."""
        try:
            self._flush()
        except OSError as exc:
            raise self._failed(exc) from None

    def _flush(self) -> None:
        self._last_flush = time.monotonic()
        if self._file is None or self._broken:
            return
        self._file.mcap.flush()
        self._file.pack_chunk_indexes()
        if self.fsync:
            os.fsync(self._file.stream.fileno())
        if self.max_bag_size and self._file.stream.tell() >= self.max_bag_size \
                and self._file.stats.count:
            self._split()

    def flush_if_due(self) -> None:
        """For a periodic timer: flush when ``flush_period`` has passed (covers idle topics)."""
        if time.monotonic() - self._last_flush >= self.flush_period:
            self.flush()

    def add_run_configuration(self, config: dict[str, Any]) -> None:
        """Store how the run was made (scene, integrator, parameters...) as MCAP metadata
        ``rigid_body_sim/run_configuration``; package version and git revision are added.
        Written to the open file now and repeated in every split file; readers use the
        last record, so calling it again updates the configuration."""
        full = {'package_version': rigid_body_sim.__version__, 'git_revision': git_revision()}
        full.update(config)
        self._run_configuration = encode_run_configuration(full)
        if self._file is not None:
            self._file.mcap.add_metadata(RUN_CONFIGURATION, self._run_configuration)

    def metadata(self) -> dict[str, Any]:
        """rosbag2 v9 ``BagMetadata`` of everything written so far."""
        return md.bag_metadata(self._files, list(self._topics.values()))

    def close(self) -> None:
        """Finish the open file (summary, indexes, footer) and write ``metadata.yaml``.
        After a write error the file cannot be finished in place: BagError with the
        command that recovers everything written before the error."""
        if self._file is None:
            return
        if not self._broken:
            try:
                self._finish_file()
            except OSError as exc:
                self._failed(exc)
        if self._broken:
            f, self._file = self._file, None
            if f is not None:
                try:
                    f.stream.close()
                except OSError:
                    pass
            raise BagError(f'{self._broken} is unfinished after the write error; the messages '
                           f'written before it are kept: {recover_hint(self.directory)}')
        md.write_metadata_yaml(self.directory, self.metadata())

    def __enter__(self) -> 'BagWriter':
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # --- internals -------------------------------------------------------------------

    def _open_next(self) -> _File:
        relpath = f'{self.name}_{len(self._files)}.mcap'
        try:
            f = _File(os.path.join(self.directory, relpath), relpath, self._compression,
                      self._chunk_size)
        except OSError as exc:
            raise BagError(f'cannot create {relpath} in {self.directory}: {exc.strerror}') from exc
        self._file = f
        self._files.append(f.stats)
        for topic in self._topics:
            self._register(f, topic)
        if self._run_configuration is not None:
            f.mcap.add_metadata(RUN_CONFIGURATION, self._run_configuration)
        return f

    def _register(self, f: _File | None, topic: str) -> None:
        if f is None:
            return
        t = self._topics[topic]
        schema = f.schemas.get(t.type)
        if schema is None:
            schema = f.mcap.register_schema(t.type, 'ros2msg',
                                            message_definition(t.type).encode())
            f.schemas[t.type] = schema
        f.channels[topic] = f.mcap.register_channel(
            topic, 'cdr', schema,
            {'offered_qos_profiles': t.offered_qos_profiles, 'topic_type_hash': t.type_hash})

    def _finish_file(self) -> None:
        f = self._file
        if f is None:
            return
        # rosbag2 reads the last "rosbag2" record of a bare .mcap; it must be complete v9.
        f.mcap.add_metadata('rosbag2', {'serialized_metadata': md.dump(self.metadata())})
        f.mcap.finish()
        f.stream.flush()
        if self.fsync:
            os.fsync(f.stream.fileno())
        f.stream.close()
        self._file = None

    def _split(self) -> _File:
        self._finish_file()
        return self._open_next()

"""Rebuild a valid, indexed MCAP from an unfinished one (writer killed before finish()).

Like ``mcap recover``: stream the records that are complete (whole chunks pass their CRC),
stop at the first damaged or missing one, and write them again with fresh indexes,
statistics and footer. A bag directory is recovered file by file, with a new
``metadata.yaml``. The unfinished file stays as it was; beside it, ``<file>.recovered``
names its recovered copy, so that a recorder starting next to it does not warn again.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass, field

from mcap.records import Attachment, Channel, DataEnd, Footer, Header, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from rigid_body_sim.bag import metadata as md
from rigid_body_sim.bag.errors import BagError
from rigid_body_sim.bag.reader import MAGIC, bag_files, is_finished
from rigid_body_sim.bag.writer import CHUNK_SIZE


@dataclass
class Recovered:
    source: str
    output: str
    messages: int = 0
    complete: bool = False          # the input ended cleanly (was not truncated)
    stopped_at: str = ''            # why reading stopped early
    stats: md.FileStats | None = None
    topics: dict[str, md.TopicStats] = field(default_factory=dict)


def recover_file(source: str, output: str) -> Recovered:
    """Copy every intact record of ``source`` into a new finished file ``output``."""
    try:
        with open(source, 'rb') as f:
            if f.read(8) != MAGIC:
                raise BagError(f'{source}: not an MCAP file')
    except OSError as exc:
        raise BagError(f'{source}: cannot read ({exc.strerror})') from exc
    if os.path.exists(output):
        raise BagError(f'{output}: already exists; choose a new output path')
    result = Recovered(source, output, stats=md.FileStats(os.path.basename(output)))
    schemas: dict[int, int] = {}
    schema_names: dict[int, str] = {}
    channels: dict[int, int] = {}
    channel_topics: dict[int, str] = {}
    header: Header | None = None
    writer: Writer | None = None
    with open(source, 'rb') as src, open(output, 'xb') as dst:
        try:
            reader = StreamReader(src, validate_crcs=True,
                                  record_size_limit=os.path.getsize(source))
            for record in reader.records:
                if isinstance(record, Header):
                    header = record
                    writer = Writer(dst, chunk_size=CHUNK_SIZE, compression=CompressionType.ZSTD)
                    writer.start(profile=record.profile, library=record.library)
                elif writer is None:
                    break
                elif isinstance(record, Schema) and record.id not in schemas:
                    schemas[record.id] = writer.register_schema(record.name, record.encoding,
                                                                record.data)
                    schema_names[record.id] = record.name
                elif isinstance(record, Channel) and record.id not in channels:
                    if record.schema_id and record.schema_id not in schemas:
                        continue  # its schema was lost; so are its messages
                    channels[record.id] = writer.register_channel(
                        record.topic, record.message_encoding,
                        schemas.get(record.schema_id, 0), dict(record.metadata))
                    channel_topics[record.id] = record.topic
                    result.topics[record.topic] = md.TopicStats(
                        record.topic, schema_names.get(record.schema_id, ''),
                        record.metadata.get('offered_qos_profiles', ''),
                        record.metadata.get('topic_type_hash', ''))
                elif isinstance(record, Message) and record.channel_id in channels:
                    writer.add_message(channels[record.channel_id], record.log_time,
                                       record.data, record.publish_time, record.sequence)
                    topic = channel_topics[record.channel_id]
                    result.stats.add(topic, record.log_time)
                    result.topics[topic].count += 1
                    result.messages += 1
                elif isinstance(record, Metadata) and record.name != 'rosbag2':
                    writer.add_metadata(record.name, dict(record.metadata))
                elif isinstance(record, Attachment):
                    writer.add_attachment(record.create_time, record.log_time, record.name,
                                          record.media_type, record.data)
                elif isinstance(record, (DataEnd, Footer)):
                    result.complete = True
                    break
        except Exception as exc:  # truncated or damaged record: keep what came before
            result.stopped_at = f'{type(exc).__name__}: {exc}'.strip()
        if writer is None or header is None:
            dst.close()
            os.unlink(output)
            raise BagError(f'{source}: no intact MCAP header; nothing to recover')
        writer.finish()
    _mark_recovered(source, output)
    return result


RECOVERED_SUFFIX = '.recovered'


def _mark_recovered(source: str, output: str) -> None:
    """Note beside ``source`` where its recovered copy is, and the size it was recovered at."""
    try:
        with open(source + RECOVERED_SUFFIX, 'w', encoding='utf-8') as f:
            json.dump({'output': os.path.abspath(output), 'size': os.path.getsize(source)}, f)
    except OSError:  # a read-only source: the copy is made; the recorder keeps its warning
        pass


def recovered_copy(source: str) -> str | None:
    """The finished copy ``bag recover`` made of the unfinished ``source``, if it still
    exists and ``source`` has not grown since; else None."""
    try:
        with open(source + RECOVERED_SUFFIX, encoding='utf-8') as f:
            mark = json.load(f)
        output, size = str(mark['output']), int(mark['size'])
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if size != os.path.getsize(source) or not is_finished(output):
        return None
    return output


def recover(source: str, output: str) -> list[Recovered]:
    """Recover a file into ``output`` (a file path, or a directory to put it in) or a bag
    directory into a new bag directory ``output`` with a fresh ``metadata.yaml``."""
    if not os.path.exists(source):
        raise BagError(f'{source}: no such file or directory')
    if os.path.isfile(source):
        if os.path.isdir(output):
            output = os.path.join(output, os.path.basename(source))
        return [recover_file(source, output)]
    files = bag_files(source)
    if os.path.exists(output) and (not os.path.isdir(output) or os.listdir(output)):
        raise BagError(f'{output}: already exists; choose a new output directory')
    os.makedirs(output, exist_ok=True)
    results = [recover_file(f, os.path.join(output, os.path.basename(f))) for f in files]
    topics: dict[str, md.TopicStats] = {}
    for r in results:
        for name, t in r.topics.items():
            merged = topics.setdefault(name, md.TopicStats(t.name, t.type,
                                                           t.offered_qos_profiles, t.type_hash))
            merged.count += t.count
    md.write_metadata_yaml(output, md.bag_metadata([r.stats for r in results if r.stats],
                                                   list(topics.values())))
    return results


def unfinished_files(directory: str) -> list[str]:
    """``.mcap`` files in ``directory`` and its subdirectories (one level) lacking a footer."""
    found = []
    if not os.path.isdir(directory):
        return found
    for root, dirs, files in os.walk(directory):
        depth = root[len(directory):].count(os.sep)
        if depth >= 1:
            dirs[:] = []
        found += [os.path.join(root, f) for f in sorted(files)
                  if f.endswith('.mcap') and not is_finished(os.path.join(root, f))]
    return found

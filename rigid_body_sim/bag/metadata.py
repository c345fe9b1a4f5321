"""rosbag2 version-9 bag metadata (``metadata.yaml`` and the in-file ``rosbag2`` record).

Jazzy decodes metadata.yaml with yaml-cpp ``.as<>``, which throws on a missing key, so
every key is always written.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

import yaml

from rigid_body_sim.bag.schema import parse_qos_yaml

VERSION = 9
METADATA_FILE = 'metadata.yaml'


@dataclass
class TopicStats:
    name: str
    type: str
    offered_qos_profiles: str = ''
    type_hash: str = ''
    count: int = 0


@dataclass
class FileStats:
    path: str                      # relative to the bag directory
    start_ns: int = 0
    end_ns: int = 0
    count: int = 0
    topic_counts: dict[str, int] = field(default_factory=dict)

    def add(self, topic: str, log_time_ns: int) -> None:
        if self.count == 0 or log_time_ns < self.start_ns:
            self.start_ns = log_time_ns
        if log_time_ns > self.end_ns:
            self.end_ns = log_time_ns
        self.count += 1
        self.topic_counts[topic] = self.topic_counts.get(topic, 0) + 1


def bag_metadata(files: list[FileStats], topics: list[TopicStats]) -> dict[str, Any]:
    """The ``BagMetadata`` mapping (without the ``rosbag2_bagfile_information`` wrapper)."""
    used = [f for f in files if f.count]
    start = min((f.start_ns for f in used), default=0)
    end = max((f.end_ns for f in used), default=0)
    return {
        'version': VERSION,
        'storage_identifier': 'mcap',
        'duration': {'nanoseconds': end - start},
        'starting_time': {'nanoseconds_since_epoch': start},
        'message_count': sum(f.count for f in files),
        'topics_with_message_count': [{
            'topic_metadata': {
                'name': t.name,
                'type': t.type,
                'serialization_format': 'cdr',
                'offered_qos_profiles': parse_qos_yaml(t.offered_qos_profiles),
                'type_description_hash': t.type_hash,
            },
            'message_count': t.count,
        } for t in topics],
        'compression_format': '',
        'compression_mode': '',
        'relative_file_paths': [f.path for f in files],
        'files': [{
            'path': f.path,
            'starting_time': {'nanoseconds_since_epoch': f.start_ns},
            'duration': {'nanoseconds': f.end_ns - f.start_ns},
            'message_count': f.count,
        } for f in files],
        'custom_data': None,
        'ros_distro': 'jazzy',
    }


def dump(meta: dict[str, Any]) -> str:
    return yaml.safe_dump(meta, sort_keys=False, default_flow_style=False)


def write_metadata_yaml(directory: str, meta: dict[str, Any]) -> str:
    """Write ``<directory>/metadata.yaml`` atomically (a crash never leaves half a file)."""
    path = os.path.join(directory, METADATA_FILE)
    tmp = path + '.tmp'
    with open(tmp, 'w', encoding='utf-8') as f:
        f.write(dump({'rosbag2_bagfile_information': meta}))
    os.replace(tmp, path)
    return path


def read_metadata_yaml(directory: str) -> dict[str, Any] | None:
    path = os.path.join(directory, METADATA_FILE)
    if not os.path.isfile(path):
        return None
    with open(path, encoding='utf-8') as f:
        data = yaml.safe_load(f)
    if not isinstance(data, dict) or 'rosbag2_bagfile_information' not in data:
        raise ValueError(f'{path}: not a rosbag2 metadata file')
    return data['rosbag2_bagfile_information']

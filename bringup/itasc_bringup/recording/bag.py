"""Storage of a recording as a rosbag2 bag (paper §6.1/§7: a recording shows the data flow, the
events and every life-cycle transition of a run; ROS tools open it as a bag).

``BagWriter(DIR)`` writes a rosbag2 bag folder as rosbag2 Jazzy writes it with its MCAP storage
plugin: ``DIR/metadata.yaml`` (metadata version 9, see :func:`bag_metadata`) and
``DIR/<name of DIR>_0.mcap``. ``BagWriter(FILE.mcap)`` writes the MCAP file alone. Either MCAP
follows the ``ros2`` profile:

* one Schema per message type: name ``pkg/msg/Type``, encoding ``ros2msg``, data the complete
  message definition (:mod:`.definitions`);
* one Channel per topic: message encoding ``cdr``, metadata ``offered_qos_profiles`` (YAML, as in
  metadata.yaml) and ``topic_type_hash`` (``RIHS01_...``);
* Messages as received, the CDR bytes untouched; log and publish time the receive time;
* a Metadata record ``rosbag2`` holding ``serialized_metadata`` (the bag metadata as YAML) and
  ``ros_distro``, written when the recording ends.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import yaml
from mcap.writer import CompressionType, Writer
from rclpy.qos import QoSProfile

from itasc_core.communication.qos import qos_profiles

from .definitions import definition, type_hash

__all__ = ['BagWriter', 'BagExists', 'CannotRecord', 'bag_metadata', 'qos_profiles', 'mcap_path_of',
           'prepare_recording', 'METADATA_VERSION', 'ROS_DISTRO',
           'APPLICATION_KEY', 'DEPLOY_KEY']

#: The key of a bag's ``custom_data`` that holds the application model file it was recorded from.
APPLICATION_KEY = 'itasc.application'
#: ... and the one that holds how it was deployed (``single`` or ``per-composite``).
DEPLOY_KEY = 'itasc.deploy'
#: The metadata version rosbag2 Jazzy writes.
METADATA_VERSION = 9
ROS_DISTRO = 'jazzy'
_COMPRESSION = {'none': CompressionType.NONE, 'lz4': CompressionType.LZ4, 'zstd': CompressionType.ZSTD}


class CannotRecord(OSError):
    """No recording can be written where it was asked for (a folder that cannot be made, a file
    that cannot be created)."""


class BagExists(CannotRecord, FileExistsError):
    """The bag folder exists and is not empty, or the MCAP file exists: a recording never
    overwrites another."""


def _dump(value: Any) -> str:
    return yaml.safe_dump(value, sort_keys=False, default_flow_style=False)


def bag_metadata(*, file_name: str, topics: list[dict[str, Any]], start_ns: int, end_ns: int,
                 custom_data: Mapping[str, str] | None = None) -> dict[str, Any]:
    """The ``rosbag2_bagfile_information`` of one MCAP file, field by field in rosbag2 Jazzy's
    order. ``topics``: ``{name, type, offered_qos_profiles, type_description_hash, message_count}``;
    ``custom_data``: what ``ros2 bag record --custom-data KEY=VALUE`` keeps."""
    count = sum(t['message_count'] for t in topics)
    start = start_ns if count else 0
    duration = max(end_ns - start_ns, 0) if count else 0
    return {
        'version': METADATA_VERSION,
        'storage_identifier': 'mcap',
        'duration': {'nanoseconds': duration},
        'starting_time': {'nanoseconds_since_epoch': start},
        'message_count': count,
        'topics_with_message_count': [{
            'topic_metadata': {
                'name': t['name'],
                'type': t['type'],
                'serialization_format': 'cdr',
                'offered_qos_profiles': t['offered_qos_profiles'],
                'type_description_hash': t['type_description_hash'],
            },
            'message_count': t['message_count'],
        } for t in topics],
        'compression_format': '',
        'compression_mode': '',
        'relative_file_paths': [file_name],
        'files': [{
            'path': file_name,
            'starting_time': {'nanoseconds_since_epoch': start},
            'duration': {'nanoseconds': duration},
            'message_count': count,
        }],
        'custom_data': dict(custom_data) if custom_data else None,
        'ros_distro': ROS_DISTRO,
    }


def mcap_path_of(path: Path) -> Path:
    """The MCAP file of the recording ``path``: ``path`` itself if it ends in ``.mcap``, else the
    bag folder's ``<name>_0.mcap``."""
    return path if path.suffix == '.mcap' else path / f'{path.name}_0.mcap'


def prepare_recording(path: Path) -> Path:
    """The MCAP file of the new recording ``path``, created empty with its folders, before
    anything is recorded; raises :class:`BagExists` where it would overwrite a recording or a file
    (a bag folder that is not new or empty, an existing ``.mcap`` file), :class:`CannotRecord`
    where nothing can be written (the error of the file system in words)."""
    mcap = mcap_path_of(path)
    try:
        if path.suffix == '.mcap' and (path.exists() or path.is_symlink()):
            raise BagExists(f'{path} exists already; a recording never overwrites a file')
        if path.suffix != '.mcap' and path.exists() and (not path.is_dir() or any(path.iterdir())):
            raise BagExists(f'{path} exists already; a bag is written into a new (or empty) folder')
        mcap.parent.mkdir(parents=True, exist_ok=True)
        with open(mcap, 'xb'):
            pass
    except BagExists:
        raise
    except OSError as err:
        raise CannotRecord(f'{path}: no recording can be written there ({err.strerror or err})') from None
    return mcap


class BagWriter:
    """Writes one recording: a bag folder, or a bare MCAP file when ``path`` ends in ``.mcap``."""

    def __init__(self, path: str | os.PathLike, *, compression: str = 'zstd', library: str = 'itasc_bringup',
                 custom_data: Mapping[str, str] | None = None, prepared: bool = False) -> None:
        """``prepared``: :func:`prepare_recording` made its empty MCAP file already."""
        path = Path(path)
        self.custom_data = dict(custom_data or {})
        self.folder: Path | None = None if path.suffix == '.mcap' else path
        self.mcap_path = mcap_path_of(path) if prepared else prepare_recording(path)
        self._stream = open(self.mcap_path, 'wb')
        self._writer = Writer(self._stream, compression=_COMPRESSION[compression])
        self._writer.start(profile='ros2', library=library)
        self._schemas: dict[str, int] = {}
        self._topics: dict[int, dict[str, Any]] = {}
        self._start = 2 ** 63 - 1
        self._end = 0
        self.closed = False

    def add_topic(self, topic: str, type_name: str, *, offered: Iterable[QoSProfile] = (),
                  profiles: list[dict[str, Any]] | None = None) -> int:
        """Register ``topic`` with the QoS profiles its publishers ``offered`` (or those
        ``profiles``, as :func:`qos_profiles` gives them); returns its channel id. Raises
        DefinitionNotFound for an unknown type."""
        encoding, text = definition(type_name)
        digest = type_hash(type_name)
        profiles = qos_profiles(offered) if profiles is None else profiles
        schema_id = self._schemas.get(type_name)
        if schema_id is None:
            schema_id = self._schemas[type_name] = self._writer.register_schema(type_name, encoding, text.encode())
        channel_id = self._writer.register_channel(topic, 'cdr', schema_id, {
            'offered_qos_profiles': _dump(profiles), 'topic_type_hash': digest})
        self._topics[channel_id] = {'name': topic, 'type': type_name, 'offered_qos_profiles': profiles,
                                    'type_description_hash': digest, 'message_count': 0}
        return channel_id

    def write(self, channel_id: int, data: bytes, *, time_ns: int, publish_time_ns: int | None = None) -> None:
        """Write one message received at ``time_ns`` (the MCAP log time) and sent at
        ``publish_time_ns`` (the publisher's DDS source timestamp, as rosbag2 records it; the
        receive time when unknown)."""
        self._writer.add_message(channel_id, log_time=time_ns, data=data,
                                 publish_time=time_ns if publish_time_ns is None else publish_time_ns)
        self._topics[channel_id]['message_count'] += 1
        self._start = min(self._start, time_ns)
        self._end = max(self._end, time_ns)

    def flush(self) -> None:
        """Write out what is buffered so far (``mcap recover`` salvages it after a SIGKILL)."""
        self._writer.flush()
        self._stream.flush()

    def metadata(self) -> dict[str, Any]:
        return bag_metadata(file_name=self.mcap_path.name, topics=list(self._topics.values()),
                            start_ns=self._start, end_ns=self._end, custom_data=self.custom_data)

    def close(self) -> None:
        """Finish the MCAP file (rosbag2 metadata record, summary, footer), then metadata.yaml."""
        if self.closed:
            return
        self.closed = True
        metadata = self.metadata()
        try:
            self._writer.add_metadata('rosbag2', {'serialized_metadata': _dump(metadata), 'ros_distro': ROS_DISTRO})
            self._writer.finish()
        finally:
            self._stream.close()
        if self.folder is not None:
            tmp = self.folder / 'metadata.yaml.tmp'
            tmp.write_text(_dump({'rosbag2_bagfile_information': metadata}), encoding='utf-8')
            tmp.replace(self.folder / 'metadata.yaml')

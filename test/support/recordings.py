"""Reading a recording back in tests: every message decoded (rosbags), with its MCAP log time
(when the recorder received it) as ``_log`` and its publish time (when its publisher sent it, the
DDS source timestamp) as ``_sent``, both in seconds. Compare messages of different topics by
``_sent``: a busy recorder may take one topic's messages later than another's."""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

from mcap.reader import make_reader
from rosbags.highlevel import AnyReader

__all__ = ['read_recording']


def read_recording(path: Path, *topics: str) -> dict[str, list]:
    """The messages of ``topics`` (all topics if none given) in ``path`` (an MCAP file or a
    rosbag2 folder), by topic, in log-time order."""
    files = sorted(path.glob('*.mcap')) if path.is_dir() else [path]
    out: dict[str, list] = defaultdict(list)
    with AnyReader([path]) as typed:
        for file in files:
            with file.open('rb') as stream:
                for schema, channel, message in make_reader(stream).iter_messages(
                        topics=list(topics) or None, log_time_order=True):
                    msg = typed.deserialize(message.data, schema.name)
                    msg._log, msg._sent = message.log_time * 1e-9, message.publish_time * 1e-9
                    out[channel.topic].append(msg)
    return out

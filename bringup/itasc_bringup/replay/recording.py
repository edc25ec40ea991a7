"""What a replay reads from a recording (rosbag2 folder or bare MCAP file, as ``--record`` writes).

Every message comes with its publish time, the DDS send time of its publisher (the recorder
writes it as the MCAP publish time). The ticks of a program are the stamps ``t`` of its
``command`` (program time, one per Scheduler tick); tick ``k`` began when the first message stamped
``t_k`` of the program was sent. Send times place every other message between ticks: a message
sent after tick ``k`` began and before tick ``k + 1`` began is in *gap* ``k`` (gap -1: before the
first tick), which is when a replay must re-create it or expect its effect.
"""

from __future__ import annotations

import bisect
import importlib
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

__all__ = ['ReplayError', 'Recording', 'RecordedEvent', 'RecordedState', 'read_recording', 'nanoseconds',
           'topic_names', 'custom_data', 'message_class', 'is_stamped']


class ReplayError(Exception):
    """BAG or MODEL cannot be replayed; the message says why."""


@dataclass(frozen=True)
class RecordedEvent:
    topic: str
    source: str
    name: str
    detail: str
    priority: bool
    sent: float


@dataclass(frozen=True)
class RecordedState:
    """A Coordinator's state change: ``state`` entered on ``event``."""

    topic: str
    state: str
    event: str
    sent: float


@dataclass
class Recording:
    """The recorded messages a replay needs, by topic, in send order."""

    #: program time of every tick, in nanoseconds (command stamps), ascending
    ticks: list[int]
    #: send time at which each tick began
    starts: list[float]
    events: list[RecordedEvent]
    states: list[RecordedState]
    #: topic -> [(send time, message)] of the data topics read
    samples: dict[str, list[tuple[float, Any]]] = field(default_factory=dict)

    def gap(self, sent: float) -> int:
        """The gap a message sent at ``sent`` belongs to: after tick ``gap`` began (-1: before any)."""
        return bisect.bisect_right(self.starts, sent) - 1

    def computed(self, prefix: str) -> list[bool]:
        """Per tick, whether a topic under ``prefix`` has a message stamped with the tick's time
        (whether the entity or composite there computed at that tick)."""
        index = {t: k for k, t in enumerate(self.ticks)}
        found = [False] * len(self.ticks)
        for topic, samples in self.samples.items():
            if topic.startswith(prefix):
                for _, msg in samples:
                    k = _tick_of(index, msg)
                    if k is not None:
                        found[k] = True
        return found

    def per_tick(self, topic: str) -> list[Any]:
        """The first message of ``topic`` stamped with each tick's time, or None (not computed)."""
        first: dict[int, Any] = {}
        for _, msg in self.samples.get(topic, []):
            first.setdefault(nanoseconds(msg), msg)
        return [first.get(t) for t in self.ticks]


def nanoseconds(msg) -> int:
    """A message's stamp (``header.stamp`` or ``stamp``) in nanoseconds."""
    s = msg.header.stamp if hasattr(msg, 'header') else msg.stamp
    return s.sec * 1_000_000_000 + s.nanosec


def message_class(type_name: str) -> type:
    """The rclpy class of a message type name, e.g. ``sensor_msgs/msg/JointState``."""
    package, kind, name = type_name.split('/')
    return getattr(importlib.import_module(f'{package}.{kind}'), name)


def is_stamped(type_name: str) -> bool:
    """Whether messages of this type carry a stamp (``header.stamp`` or ``stamp``)."""
    fields = message_class(type_name).get_fields_and_field_types()  # type: ignore[attr-defined]  # rosidl
    return 'header' in fields or 'stamp' in fields


def _stamp_of(msg) -> int | None:
    """A data message's stamp in nanoseconds; None for an unstamped one (a labelled table)."""
    return nanoseconds(msg) if hasattr(msg, 'header') or hasattr(msg, 'stamp') else None


def _tick_of(index: dict[int, int], msg) -> int | None:
    """The tick whose time ``msg`` is stamped with, None if none (or unstamped)."""
    stamp = _stamp_of(msg)
    return None if stamp is None else index.get(stamp)


def _files(bag: Path) -> list[Path]:
    return sorted(bag.glob('*.mcap')) if bag.is_dir() else [bag]


def custom_data(bag: Path) -> dict[str, str]:
    """The bag's ``custom_data`` (rosbag2's metadata, kept in its MCAP files' ``rosbag2`` record;
    empty for a recording that was never closed)."""
    import yaml
    from mcap.reader import make_reader

    data: dict[str, str] = {}
    try:
        for file in _files(bag):
            with file.open('rb') as stream:
                for record in make_reader(stream).iter_metadata():
                    if record.name == 'rosbag2' and 'serialized_metadata' in record.metadata:
                        info = yaml.safe_load(record.metadata['serialized_metadata']) or {}
                        data.update(info.get('custom_data') or {})
    except Exception:  # noqa: BLE001 - no metadata to be had: what topic_names says about the bag follows
        return {}
    return data


def topic_names(bag: Path) -> list[str]:
    """The topics recorded in ``bag``."""
    from mcap.reader import make_reader

    try:
        names = []
        for file in _files(bag):
            with file.open('rb') as stream:
                summary = make_reader(stream).get_summary()
                names += [c.topic for c in summary.channels.values()] if summary else []
        return names
    except Exception as err:  # noqa: BLE001 - mcap raises several kinds for a file that is not an MCAP
        raise ReplayError(_unreadable(bag, err)) from None


def _messages(bag: Path, wanted: Callable[[str], bool]):
    """``(topic, send time, rclpy message)`` of the topics ``wanted`` picks, in log-time order."""
    from mcap.reader import make_reader
    from rclpy.serialization import deserialize_message

    classes: dict[str, type] = {}
    files = _files(bag)
    if not files:
        raise ReplayError(f'{bag}: not a readable bag (no .mcap file in it)')
    try:
        for file in files:
            with file.open('rb') as stream:
                for schema, channel, message in make_reader(stream).iter_messages(log_time_order=True):
                    if not wanted(channel.topic):
                        continue
                    cls = classes.get(schema.name)
                    if cls is None:
                        cls = classes[schema.name] = message_class(schema.name)
                    yield channel.topic, message.publish_time * 1e-9, deserialize_message(message.data, cls)
    except ReplayError:
        raise
    except Exception as err:  # noqa: BLE001 - mcap and the deserializer raise several kinds for a broken file
        raise ReplayError(_unreadable(bag, err)) from None


def _unreadable(bag: Path, err: Exception) -> str:
    """Why ``bag`` cannot be read, and what may make it readable (a recording cut off by a kill)."""
    files = ' '.join(str(f) for f in _files(bag))
    return (f'{bag}: not a readable bag ({type(err).__name__}: {err}); if its recording was cut off, '
            f'itasc-recover {files} writes a readable copy of what it holds')


def read_recording(bag: Path, *, commands: list[str], outputs: set[str], inputs: set[str], events_under: str,
                   states: set[str]) -> Recording:
    """Read ``bag``: the tick times from the ``commands`` topics, the messages of the programs'
    stamped ``outputs`` (the first stamped with a tick's time tells when the tick began) and of
    their ``inputs``, the events of every event topic under ``events_under`` and the Coordinator states
    on the ``states`` topics."""
    from itasc_msgs.msg import CoordinatorState, Event

    samples: dict[str, list[tuple[float, Any]]] = defaultdict(list)
    events: list[RecordedEvent] = []
    recorded_states: list[RecordedState] = []
    wanted = set(commands) | outputs | inputs | states

    def picked(topic: str) -> bool:
        return topic in wanted or (topic.startswith(events_under) and topic.endswith('/events'))

    for topic, sent, msg in _messages(bag, picked):
        if isinstance(msg, Event):
            events.append(RecordedEvent(topic, msg.source, msg.name, msg.detail, msg.priority, sent))
        elif isinstance(msg, CoordinatorState):
            recorded_states.append(RecordedState(topic, msg.state, msg.event, sent))
        else:
            samples[topic].append((sent, msg))
    ticks = sorted({nanoseconds(msg) for topic in commands for _, msg in samples.get(topic, [])})
    if not ticks:
        raise ReplayError(f'{bag}: no messages on {", ".join(commands)}')
    index = {t: k for k, t in enumerate(ticks)}
    starts = [float('inf')] * len(ticks)
    for topic in outputs | set(commands):
        for sent, msg in samples.get(topic, []):
            k = _tick_of(index, msg)
            if k is not None:
                starts[k] = min(starts[k], sent)
    by_send = lambda item: item.sent  # noqa: E731
    return Recording(ticks, starts, sorted(events, key=by_send), sorted(recorded_states, key=by_send),
                     {t: sorted(s, key=lambda item: item[0]) for t, s in samples.items()})

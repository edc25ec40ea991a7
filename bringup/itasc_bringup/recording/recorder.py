"""The run recorder: an rclpy node that records every topic under a namespace to one MCAP file,
written as a ROS 2 bag (SPEC, product paragraph: "... while recording the whole run to MCAP";
paper §6.1/§7: Coordinators publish their state and composites their events, so a recording
shows the data flow, the events and every life-cycle transition of a run).

The file follows the MCAP ``ros2`` profile as rosbag2's MCAP storage plugin writes it:

* one Schema per message type: name ``pkg/msg/Type``, encoding ``ros2msg``, data the complete
  concatenated message definition (see :mod:`.msgdefs`);
* one Channel per topic: message encoding ``cdr``, metadata ``offered_qos_profiles`` (the
  publishers' QoS as rosbag2's YAML, version 9) and ``topic_type_hash`` (``RIHS01_...``);
* Messages as received: the CDR bytes untouched (``raw=True`` subscriptions), log time and
  publish time both the receive time (ns since the epoch).

Topics are discovered, not listed: every ``scan_period`` the node looks at the ROS graph and
subscribes to each new topic under ``prefix`` with a QoS that matches its publishers: keep-last
``depth``, reliable unless a publisher is best effort, transient local when all publishers offer
it (the Coordinators' latched ``.../state`` topics: a state published before the recorder
subscribed is still recorded).

Ending a recording: :meth:`Recorder.close` finishes the file (MCAP summary and footer) and is
idempotent; ``destroy_node()`` and interpreter exit (atexit) call it too. With rclpy's default signal handling, SIGINT/SIGTERM make ``spin`` raise
(``KeyboardInterrupt`` / ``ExternalShutdownException``) so the caller's ``finally`` runs; for a
process that disables rclpy's handlers, :func:`install_signal_handlers` does the job. Only a
SIGKILL loses the summary; the file is flushed every ``flush_period`` so that ``mcap recover``
can still salvage the data.
"""

from __future__ import annotations

import atexit
import functools
import importlib
import os
import signal
import sys
import threading
import time
import weakref
from collections.abc import Iterable
from typing import Any

import yaml
from mcap.writer import CompressionType, Writer
from rclpy.context import Context
from rclpy.node import Node
from rclpy.qos import (DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile,
                       ReliabilityPolicy)

from .msgdefs import DefinitionNotFound, full_definition

__all__ = ['Recorder', 'install_signal_handlers', 'main']

_COMPRESSION = {'none': CompressionType.NONE, 'lz4': CompressionType.LZ4,
                'zstd': CompressionType.ZSTD}


def _duration_yaml(duration: Any) -> dict[str, int]:
    ns = int(duration.nanoseconds)
    return {'sec': ns // 1_000_000_000, 'nsec': ns % 1_000_000_000}


def qos_profiles_yaml(profiles: Iterable[QoSProfile]) -> str:
    """The ``offered_qos_profiles`` channel metadata, as rosbag2 serializes it (version 9)."""
    return yaml.safe_dump([{
        'history': HistoryPolicy(p.history).name.lower(),
        'depth': int(p.depth),
        'reliability': ReliabilityPolicy(p.reliability).name.lower(),
        'durability': DurabilityPolicy(p.durability).name.lower(),
        'deadline': _duration_yaml(p.deadline),
        'lifespan': _duration_yaml(p.lifespan),
        'liveliness': LivelinessPolicy(p.liveliness).name.lower(),
        'liveliness_lease_duration': _duration_yaml(p.liveliness_lease_duration),
        'avoid_ros_namespace_conventions': bool(p.avoid_ros_namespace_conventions),
    } for p in profiles], sort_keys=False, default_flow_style=False)


def _import_message(type_name: str) -> type:
    package, kind, name = type_name.split('/')
    return getattr(importlib.import_module(f'{package}.{kind}'), name)


def _under(topic: str, prefix: str) -> bool:
    prefix = '/' + prefix.strip('/')
    return prefix == '/' or topic == prefix or topic.startswith(prefix + '/')


class Recorder(Node):
    """Node ``recorder``: records all topics under ``prefix`` to the MCAP file ``path``."""

    def __init__(self, path: str | os.PathLike, *, prefix: str = '/app',
                 context: Context | None = None, node_name: str = 'recorder',
                 scan_period: float = 0.2, depth: int = 1000, compression: str = 'zstd',
                 flush_period: float = 1.0, exclude: Iterable[str] = ()) -> None:
        super().__init__(node_name, context=context)
        self.path = os.fspath(path)
        self.prefix = prefix
        self.depth = depth
        self.exclude = frozenset(exclude)
        #: topic -> message type, for every topic being recorded.
        self.topics: dict[str, str] = {}
        #: topic -> number of messages written.
        self.counts: dict[str, int] = {}
        self._skipped: set[str] = set()
        self._schemas: dict[str, int] = {}
        self._lock = threading.Lock()
        self._owner: int | None = None      # thread id holding _lock while writing
        self._pending_interrupt = False
        self._closed = False
        self._last_flush = time.monotonic()
        self._flush_period = flush_period

        os.makedirs(os.path.dirname(os.path.abspath(self.path)), exist_ok=True)
        self._stream = open(self.path, 'wb')
        self._writer = Writer(self._stream, compression=_COMPRESSION[compression])
        self._writer.start(profile='ros2', library='itasc_bringup.recording (mcap python)')

        self._atexit = _weak_close(self)
        atexit.register(self._atexit)
        self._timer = self.create_timer(scan_period, self._scan)
        self._scan()

    # ----------------------------------------------------------------- discovery
    def _scan(self) -> None:
        if self._closed:
            return
        for topic, types in self.get_topic_names_and_types():
            if topic in self.topics or topic in self._skipped or topic in self.exclude:
                continue
            if not _under(topic, self.prefix):
                continue
            publishers = self.get_publishers_info_by_topic(topic)
            if not publishers:
                continue  # only subscribers so far: nothing to record, look again later
            if len(types) > 1:
                self.get_logger().warning(
                    f'{topic} has several types {types}; recording {types[0]}')
            self._subscribe_discovered(topic, types[0], publishers)
        if time.monotonic() - self._last_flush >= self._flush_period:
            self._last_flush = time.monotonic()
            with self._lock:
                if not self._closed:
                    self._writer.flush()

    def _qos(self, publishers: list) -> QoSProfile:
        offered = [p.qos_profile for p in publishers]
        best_effort = any(q.reliability == ReliabilityPolicy.BEST_EFFORT for q in offered)
        # Requesting transient local from a volatile publisher would get nothing at all.
        latched = all(q.durability == DurabilityPolicy.TRANSIENT_LOCAL for q in offered)
        return QoSProfile(
            history=HistoryPolicy.KEEP_LAST, depth=self.depth,
            reliability=(ReliabilityPolicy.BEST_EFFORT if best_effort
                         else ReliabilityPolicy.RELIABLE),
            durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)

    def record(self, topic: str, type_name: str, *, qos: QoSProfile) -> None:
        """Record ``topic`` from now on, before any publisher exists (e.g. a composite's event and
        state topics, known from the model, so that no event of the bring-up is missed)."""
        if topic not in self.topics:
            self._subscribe(topic, type_name, qos=qos, offered=[qos], type_hash='')

    def _subscribe_discovered(self, topic: str, type_name: str, publishers: list) -> None:
        type_hash = str(publishers[0].topic_type_hash)
        self._subscribe(topic, type_name, qos=self._qos(publishers), offered=[p.qos_profile for p in publishers],
                        type_hash='' if type_hash == 'INVALID' else type_hash)

    def _subscribe(self, topic: str, type_name: str, *, qos: QoSProfile, offered: list[QoSProfile],
                   type_hash: str) -> None:
        try:
            msg_class = _import_message(type_name)
            encoding, definition = full_definition(type_name)
        except (ImportError, AttributeError, ValueError, DefinitionNotFound) as err:
            self._skipped.add(topic)
            self.get_logger().warning(f'not recording {topic} ({type_name}): {err}')
            return
        metadata = {'offered_qos_profiles': qos_profiles_yaml(offered), 'topic_type_hash': type_hash}
        with self._lock:
            if self._closed:
                return
            schema_id = self._schemas.get(type_name)
            if schema_id is None:
                schema_id = self._writer.register_schema(type_name, encoding, definition.encode())
                self._schemas[type_name] = schema_id
            channel_id = self._writer.register_channel(topic, 'cdr', schema_id, metadata)
        self.topics[topic] = type_name
        self.counts[topic] = 0
        callback = functools.partial(self._write, topic, channel_id)
        self.create_subscription(msg_class, topic, callback, qos, raw=True)
        self.get_logger().debug(f'recording {topic} ({type_name})')

    # ----------------------------------------------------------------- writing
    def _write(self, topic: str, channel_id: int, data: bytes) -> None:
        stamp = time.time_ns()
        with self._lock:
            if self._closed:
                return
            self._owner = threading.get_ident()
            try:
                self._writer.add_message(channel_id, log_time=stamp, data=bytes(data),
                                         publish_time=stamp)
                self.counts[topic] += 1
            finally:
                self._owner = None
        if self._pending_interrupt:  # a signal arrived during the write above
            self.close()
            raise KeyboardInterrupt

    @property
    def closed(self) -> bool:
        return self._closed

    def close(self) -> None:
        """Finish the MCAP file (summary, footer) and close it. Safe to call any number of
        times, from any thread, before or after the node or its context is destroyed."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            try:
                self._writer.finish()
            finally:
                self._stream.close()
        atexit.unregister(self._atexit)

    def destroy_node(self) -> None:
        self.close()
        super().destroy_node()


def _weak_close(recorder: Recorder):
    ref = weakref.ref(recorder)

    def close() -> None:
        r = ref()
        if r is not None:
            r.close()
    return close


def install_signal_handlers(recorder: Recorder, *,
                            signals: Iterable[int] = (signal.SIGINT, signal.SIGTERM)) -> None:
    """Make ``signals`` finish the recording, then raise KeyboardInterrupt in the main thread.

    Needed only when rclpy's own handlers are off (``rclpy.init(signal_handler_options=
    SignalHandlerOptions.NO)``) or the main thread does not spin: call it from the main thread,
    after ``rclpy.init()`` (it replaces rclpy's handlers for these signals). A signal that
    interrupts a write in progress on the main thread lets that write complete first.
    """
    def handler(signum: int, frame: Any) -> None:
        if recorder._owner == threading.get_ident():
            recorder._pending_interrupt = True
            return
        recorder.close()
        raise KeyboardInterrupt(f'signal {signum}')

    for signum in signals:
        signal.signal(signum, handler)


def main(argv: list[str] | None = None) -> int:
    """``python -m itasc_bringup.recording.recorder OUT.mcap [--prefix /app]``."""
    import argparse

    import rclpy
    from rclpy.executors import ExternalShutdownException

    from itasc_core.communication.dds import configure_dds

    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('path')
    parser.add_argument('--prefix', default='/app')
    args = parser.parse_args(argv)
    configure_dds()
    rclpy.init()
    recorder = None
    try:
        recorder = Recorder(args.path, prefix=args.prefix)
        rclpy.spin(recorder)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if recorder is not None:
            recorder.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())

"""The run recorder: an rclpy node that records every topic under a namespace to a rosbag2 bag
(SPEC, product paragraph: "... while recording the whole run to MCAP"; paper §6.1/§7:
Coordinators publish their state and composites their events, so a recording shows the data
flow, the events and every life-cycle transition of a run).

``Recorder(DIR)`` writes a rosbag2 bag folder (``metadata.yaml`` and one MCAP file) that
``ros2 bag info/play`` and rosbags open; ``Recorder(FILE.mcap)`` writes the MCAP file alone
(:mod:`.bag` describes both).

Topics known from the model are recorded from the start: :meth:`Recorder.record_model`
subscribes to every data-flow topic of a composition model, and :meth:`Recorder.record` to any
other topic (a composite's event and state topics), before any publisher exists, so the first
tick is in the recording, and so is every output of the recorder's own process under ``prefix``,
data flow of the model or not (a Driver's ``<robot>/joint_states``), from its first sample. Other
topics are discovered: every ``scan_period`` the node looks at
the ROS graph and subscribes to new topics under ``prefix`` (a few per scan:
:data:`QUERIES_PER_SCAN`) with a QoS that matches its
publishers: keep-last ``depth``, reliable unless a publisher is best effort, transient local when
all publishers offer it (the Coordinators' latched ``.../state`` topics, the event topics). A
publisher that appears later and that no reader of the topic matches (a volatile one where the
reader asked for transient local, e.g. ``ros2 topic pub`` on an event topic; a best-effort one
where it asked for reliable) gets a volatile reader of its own; a message that reaches the
recorder through two readers is written once (:mod:`.duplicates`).

Recording stays off the control path (issue #9). A data-flow output in this process is *tapped*
(:mod:`..observe`): the tick hands the sample over and pays no DDS send for the recorder; the
samples are turned into CDR bytes between ticks (:meth:`Recorder.drain`, :mod:`itasc_core.communication.cdr`: a few
microseconds each, no ROS message built), and a process of its own compresses and writes the bag
(:mod:`.writer`). A composite process of this machine records its own outputs the same way and
streams them to that process (:attr:`Recorder.stream_address`,
:mod:`itasc_core.communication.sample_stream`): a topic its stream announces is read by no DDS
reader here (``elsewhere`` leaves out those known from the model; any other is dropped when the
writer names it). Any other topic of another process is read over DDS as its raw bytes.

:meth:`Recorder.last` answers whether (and what) a topic's newest message was written, e.g. a
composite's final state before the recording is closed.

Ending a recording: :meth:`Recorder.close` finishes the bag and is idempotent;
``destroy_node()`` and interpreter exit (atexit) call it too. With rclpy's default signal
handling, SIGINT/SIGTERM make ``spin`` raise (``KeyboardInterrupt`` /
``ExternalShutdownException``) so the caller's ``finally`` runs; for a process that disables
rclpy's handlers, :func:`install_signal_handlers` does the job. Only a SIGKILL loses the summary
(and metadata.yaml); the MCAP file is flushed every ``flush_period`` so that ``mcap recover``
can still salvage the data.
"""

from __future__ import annotations

import atexit
import collections
import functools
import importlib
import os
import signal
import sys
import threading
import time
import weakref
from collections.abc import Callable, Iterable, Mapping
from typing import Any

from rclpy.context import Context
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from rclpy.subscription import Subscription

from itasc_core.communication.cdr import serialize_all
from itasc_core.communication.ports import OutputPort
from itasc_core.communication.qos import DATA_QOS
from itasc_core.communication.sample_stream import under

from ..observe import Observer
from .bag import qos_profiles
from .definitions import DefinitionNotFound, definition
from .duplicates import Duplicates
from .writer import BagProcess

__all__ = ['Recorder', 'install_signal_handlers', 'main']


def _import_message(type_name: str) -> type:
    package, kind, name = type_name.split('/')
    return getattr(importlib.import_module(f'{package}.{kind}'), name)


def _matches(reader: QoSProfile, writer: QoSProfile) -> bool:
    """Whether a reader asking for ``reader`` matches a writer offering ``writer`` (DDS: the offer
    must be at least the request)."""
    return (reader.reliability != ReliabilityPolicy.RELIABLE or writer.reliability == ReliabilityPolicy.RELIABLE) \
        and (reader.durability != DurabilityPolicy.TRANSIENT_LOCAL
             or writer.durability == DurabilityPolicy.TRANSIENT_LOCAL)


#: The most graph queries one scan makes. rclpy holds the interpreter in each (~0.1 ms), and a
#: control loop ticks in the same process: looking at all of an application's ~40 topics at once
#: took 4 ms, several ticks at 1 kHz. A scan looks for new topics and at the publishers of a few
#: recorded ones; a round over all of them takes several scans.
QUERIES_PER_SCAN = 4


class Recorder(Node):
    """Node ``recorder``: records all topics under ``prefix`` to the bag (folder or ``.mcap``) ``path``."""

    def __init__(self, path: str | os.PathLike, *, prefix: str = '/app',
                 context: Context | None = None, node_name: str = 'recorder',
                 scan_period: float = 0.2, depth: int = 1000, compression: str = 'zstd',
                 flush_period: float = 1.0, exclude: Iterable[str] = (),
                 custom_data: Mapping[str, str] | None = None,
                 elsewhere: Callable[[str], bool] = lambda topic: True) -> None:
        """``custom_data``: kept in the bag's metadata (``custom_data``, as ``ros2 bag record
        --custom-data`` keeps it); ``elsewhere(topic)``: whether a topic whose output is not in this
        process yet lives in another one (read over DDS from the start) or is to be tapped once its
        output appears here (:class:`..observe.Observer`)."""
        # the bag first: a path that cannot take a bag fails before any node exists
        self._bag = BagProcess(path, compression=compression, library='itasc_bringup.recording (mcap python)',
                               custom_data=custom_data)
        super().__init__(node_name, context=context)
        self.path = os.fspath(path)
        self.prefix = prefix
        self.depth = depth
        self.exclude = frozenset(exclude)
        #: topic -> message type, for every topic being recorded.
        self.topics: dict[str, str] = {}
        #: topic -> number of messages written.
        self.counts: dict[str, int] = {}
        self._last: dict[str, bytes] = {}
        self._classes: dict[str, type] = {}
        self._channels: dict[str, int] = {}
        #: topic -> the QoS each of its readers asked for
        self._readers: dict[str, list[QoSProfile]] = {}
        #: topic -> its DDS readers
        self._dds_readers: dict[str, list[Subscription]] = {}
        #: topics that the processes publishing them stream to the writer
        self._streamed: set[str] = set()
        #: topic -> its publishers when they were last matched against its readers
        self._publisher_counts: dict[str, int] = {}
        #: the topics this round of scans has yet to look at again: recorded ones (a publisher none
        #: of their readers matches?) and idle ones (a publisher yet?)
        self._round: collections.deque[str] = collections.deque()
        #: topics under ``prefix`` that had only subscribers when last looked at
        self._idle: set[str] = set()
        #: topics taken by several readers -> the copies to drop
        self._duplicates: dict[str, Duplicates] = {}
        self._listeners: list[Callable[[str], None]] = []
        self._skipped: set[str] = set()
        self._lock = threading.Lock()
        self._owner: int | None = None      # thread id holding _lock while writing
        self._pending_interrupt = False
        self._closed = False
        self._last_flush = time.monotonic()
        self._flush_period = flush_period
        self._observer = Observer(self, elsewhere=elsewhere)
        #: tapped samples not written yet: (topic, channel, tapped at [ns], sample)
        self._pending: list[tuple[str, int, int, Any]] = []
        self._observer.on_output(self._output_here)

        self._atexit = _weak_close(self)
        atexit.register(self._atexit)
        self._timer = self.create_timer(scan_period, self._scan)
        self._scan()

    # ----------------------------------------------------------------- what is recorded
    def record(self, topic: str, type_name: str, *, qos: QoSProfile) -> None:
        """Record ``topic`` from now on, before any publisher exists (e.g. a composite's event and
        state topics, known from the model, so that no event of the bring-up is missed); a
        data-flow output in this process is tapped."""
        if topic not in self.topics:
            self._subscribe(topic, type_name, qos=qos, offered=[qos])

    def record_model(self, model: Any, *, namespace: str | None = None) -> list[str]:
        """Record every data-flow topic of the composition ``model`` (living in ``namespace``,
        default ``/<model name>``) from now on; call it before the hierarchy is configured so
        that the first tick is recorded. Returns the topics."""
        from .topics import data_flow_topics
        topics = data_flow_topics(model, namespace=namespace)
        for topic, type_name in topics.items():
            self.record(topic, type_name, qos=DATA_QOS)
        return list(topics)

    @property
    def stream_address(self) -> str:
        """The abstract Unix socket that a composite process streams its outputs to
        (:class:`~itasc_core.communication.sample_stream.SampleStream`)."""
        return self._bag.address

    def _scan(self) -> None:
        if self._closed:
            return
        self.drain()
        for topic in self._bag.streamed():
            self._recorded_by_its_process(topic)
        listed = self.get_topic_names_and_types()
        budget = QUERIES_PER_SCAN - 1
        for topic, types in listed:
            if budget <= 0:
                break
            if topic not in self._readers and topic not in self._idle and topic not in self._skipped \
                    and topic not in self.exclude and topic not in self._streamed and under(topic, self.prefix):
                budget -= self._discover(topic, types)
        # a round over the recorded topics and those without a publisher, a few per scan
        tapped = self._observer.tapped
        if not self._round:
            self._round.extend(topic for topic, _ in listed if topic in self._readers or topic in self._idle)
        while self._round and budget > 0:
            topic = self._round.popleft()
            if topic in self._idle:
                self._idle.discard(topic)  # looked at again by the next scan's discovery
            elif self._readers.get(topic) and topic not in tapped and topic not in self._streamed:  # read over DDS
                budget -= self._match_new_publishers(topic)
        if time.monotonic() - self._last_flush >= self._flush_period:
            self._last_flush = time.monotonic()
            with self._lock:
                if not self._closed:
                    self._bag.flush()

    def _recorded_by_its_process(self, topic: str) -> None:
        """``topic`` comes down a stream from the process that publishes it: no DDS reader here."""
        self._streamed.add(topic)
        self._observer.drop(topic)
        for subscription in self._dds_readers.pop(topic, []):
            self.destroy_subscription(subscription)
        if topic in self._readers:
            self._readers[topic] = []

    def drain(self) -> None:
        """Write the samples tapped since the last call (call it between ticks: a few
        microseconds per sample)."""
        if not self._pending:
            return
        pending, self._pending = self._pending, []
        encoded = serialize_all(sample for *_, sample in pending)
        self._write_all([(topic, channel_id, data, tapped_at, 0, tapped_at)
                         for (topic, channel_id, tapped_at, _), data in zip(pending, encoded)])

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

    def _discover(self, topic: str, types: list[str]) -> int:
        """Record a topic not recorded yet, if it has publishers; the number of graph queries this took."""
        publishers = self.get_publishers_info_by_topic(topic)
        if not publishers:
            self._idle.add(topic)  # only subscribers so far: nothing to record, look again later
            return 1
        if len(types) > 1:
            self.get_logger().warning(f'{topic} has several types {types}; recording {types[0]}')
        self._subscribe(topic, types[0], qos=self._qos(publishers), offered=[p.qos_profile for p in publishers])
        return 2

    def _match_new_publishers(self, topic: str) -> int:
        """Give ``topic`` a volatile reader for publishers that none of its readers matches; the
        number of graph queries this took."""
        count = self.count_publishers(topic)
        if count == self._publisher_counts.get(topic):
            return 1
        self._publisher_counts[topic] = count
        readers = self._readers[topic]
        unmatched = [p for p in self.get_publishers_info_by_topic(topic)
                     if not any(_matches(reader, p.qos_profile) for reader in readers)]
        if not unmatched:
            return 2
        # volatile: a transient-local reader added now would bring in again what was written
        qos = self._qos(unmatched)
        qos.durability = DurabilityPolicy.VOLATILE
        self._duplicates.setdefault(topic, Duplicates(window=4 * max(r.depth for r in readers)))
        self._add_reader(topic, qos)
        self.get_logger().info(f'{topic}: a {qos.reliability.name.lower()} volatile reader more, for '
                               f'{", ".join(f"{p.node_namespace}/{p.node_name}" for p in unmatched)}')
        return 2

    def _output_here(self, port: OutputPort) -> None:
        """Every output of this process under ``prefix`` is recorded (tapped) from its first sample,
        data flow of the model or not (a Driver's ``<robot>/joint_states``): the graph scan finds a
        few new topics a scan, and a spinning run's began ~1-2 s late."""
        topic = port.topic
        if topic not in self.topics and topic not in self._skipped and topic not in self.exclude \
                and under(topic, self.prefix):
            self.record(topic, port.spec.msg_type_name, qos=DATA_QOS)

    def _subscribe(self, topic: str, type_name: str, *, qos: QoSProfile, offered: list[QoSProfile]) -> None:
        try:
            msg_class = _import_message(type_name)
            definition(type_name)  # an unknown type is refused here, before the writer sees it
            with self._lock:
                if self._closed:
                    return
                channel_id = self._bag.add_topic(topic, type_name, profiles=qos_profiles(offered))
        except (ImportError, AttributeError, ValueError, DefinitionNotFound) as err:
            self._skipped.add(topic)
            self.get_logger().warning(f'not recording {topic} ({type_name}): {err}')
            return
        self.topics[topic] = type_name
        self.counts[topic] = 0
        self._classes[topic] = msg_class
        self._channels[topic] = channel_id
        self._readers[topic] = []
        self._observer.observe(topic, functools.partial(self._tapped, channel_id),
                               subscribe=lambda: self._add_reader(topic, qos))
        self.get_logger().debug(f'recording {topic} ({type_name})')

    def _tapped(self, channel_id: int, topic: str, sample: Any) -> None:
        self._pending.append((topic, channel_id, time.time_ns(), sample))

    def _add_reader(self, topic: str, qos: QoSProfile) -> Subscription:
        # keep-last ``depth``, whatever the caller's profile says about the queue
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=max(self.depth, qos.depth),
                         reliability=qos.reliability, durability=qos.durability)
        readers = self._readers[topic]
        callback = functools.partial(self._received, topic, self._channels[topic], len(readers))
        subscription = self.create_subscription(self._classes[topic], topic, callback, qos, raw=True)
        self._dds_readers.setdefault(topic, []).append(subscription)
        # the callback takes the message info too (its signature alone can't say so: see _received)
        subscription._callback_type = Subscription.CallbackType.WithMessageInfo
        readers.append(qos)
        return subscription

    # ----------------------------------------------------------------- writing
    def _received(self, topic: str, channel_id: int, reader: int, *received: Any) -> None:
        # rclpy's executors pass (message, info); Jazzy's EventsExecutor passes the pair as one
        # argument (events_executor.cpp: ``callback(msg_info)``)
        data, info = received if len(received) == 2 else received[0]
        self._write(topic, channel_id, data, sent=info.get('source_timestamp') or None, reader=reader)

    def _write(self, topic: str, channel_id: int, data: bytes, *, sent: int | None, reader: int,
               received: int | None = None) -> None:
        """Write ``data`` received at ``received`` (default: now) by reader number ``reader`` of
        ``topic`` and sent at ``sent`` (the publisher's DDS source timestamp, ns): a reader orders
        messages of different topics by it, since a busy recorder may take one topic's messages
        later than another's."""
        stamp = time.time_ns() if received is None else received
        self._write_all([(topic, channel_id, bytes(data), sent, reader, stamp)])

    def _write_all(self, messages: list[tuple[str, int, bytes, int | None, int, int]]) -> None:
        """Write each ``(topic, channel, data, sent, reader, received)`` (see :meth:`_write`)."""
        with self._lock:
            if self._closed:
                return
            self._owner = threading.get_ident()
            try:
                if self._duplicates:  # topics taken by several readers: each message once
                    messages = [m for m in messages
                                if (duplicates := self._duplicates.get(m[0])) is None
                                or duplicates.new(m[2], reader=m[4])]
                self._bag.write_all([(channel_id, data, received, received if sent is None else sent)
                                     for _, channel_id, data, sent, _, received in messages])
                counts, last = self.counts, self._last
                for topic, _, data, _, _, _ in messages:
                    counts[topic] += 1
                    last[topic] = data
            finally:
                self._owner = None
        if self._listeners:
            for topic, *_ in messages:
                for listener in self._listeners:
                    listener(topic)
        if self._pending_interrupt:  # a signal arrived during the writes above
            self.close()
            raise KeyboardInterrupt

    # ----------------------------------------------------------------- what was written
    def last(self, topic: str) -> Any | None:
        """The newest message of ``topic`` written to the bag (deserialized), or None."""
        data = self._last.get(topic)
        return None if data is None else deserialize_message(data, self._classes[topic])

    def on_write(self, listener: Callable[[str], None]) -> None:
        """Call ``listener(topic)`` after every message written (in the thread that wrote it)."""
        self._listeners.append(listener)

    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def failure(self) -> str | None:
        """Why the recording is incomplete (see :attr:`~.writer.BagProcess.failure`), None while it is not."""
        return self._bag.failure

    def close(self) -> None:
        """Finish the bag (MCAP summary and footer, metadata.yaml) and close it. Safe to call any
        number of times, from any thread, before or after the node or its context is destroyed."""
        if not self._closed and threading.current_thread() is threading.main_thread():
            self.drain()
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self._observer.close()
            self._bag.close()
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
    """``python -m itasc_bringup.recording.recorder OUT_DIR|OUT.mcap [--prefix /app]``."""
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

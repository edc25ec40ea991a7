"""Data-flow ports with metadata (paper §4.3 Listing 1, §7).

A port carries the paper's metadata: ``type`` (what general kind of data), ``msg_type`` (the
platform type, here a ROS 2 message class), ``semantics`` (the geometric semantics, e.g.
``Pose(ee|base)@base``), ``id`` (the topic), ``direction`` and ``framework``. The Composer checks
that connected ports agree on all of it before connecting them.

Locality is a deployment choice: an input whose output lives in the same process is linked to it
directly (the sample object is handed over, :mod:`.samples`: no message built, no serialisation,
no executor hop); otherwise it subscribes to the output's topic over DDS and turns each message
into its sample, with one reader per topic for all the inputs of a composite that read it
(:class:`_RemoteReader`). An output publishes only while a DDS reader listens (another process, ``ros2
topic echo``), so co-located connections pay for nothing they do not need; it then sends the
sample's CDR bytes (:mod:`.cdr`), not a ROS message built from the sample and converted by rclpy
(a ``Features`` sample 145 -> 88 us a publish on a 2-core VM). Observers in the process (the
recorder, the console) *tap* an output instead of reading it over DDS (:meth:`OutputPort.tap`):
they get every sample, and the tick pays no DDS send for them.

A child composite in another process that its parent's Scheduler has switched off (a Task not
active in the current state of the Running sub-FSM) computes nothing, so its readers do not count
as listening (:meth:`LocalBus.set_idle`): data sent only to it would cost a send here and a wake-up
there every tick (``--deploy per-composite`` at 500 Hz, an inactive Task's process took 10 % of a
core). Its first tick after it is switched on again gets the sample of that tick, sent before its
trigger.
"""

from __future__ import annotations

import threading
import time
import weakref
from collections import deque
from contextlib import contextmanager
from dataclasses import dataclass, replace
from typing import Any, Callable, Iterator

from rclpy.context import Context
from rclpy.node import Node
from rclpy.serialization import deserialize_message

from .cdr import received_as_sample, serialize
from .qos import DATA_QOS, DATA_READER_QOS
from .samples import as_message, as_sample

__all__ = [
    'PortSpec',
    'InputPort',
    'OutputPort',
    'LocalBus',
    'ListenedPublisher',
    'SemanticMismatch',
    'check_connection',
]


#: How many samples of one source a ``multiple`` input keeps until its entity takes them
#: (:meth:`InputPort.take_arrived`).
ARRIVED = 64


@dataclass(frozen=True)
class PortSpec:
    """Metadata of one port (paper Listing 1)."""

    name: str
    direction: str  # 'input' | 'output'
    msg_type: type
    type: str = ''
    semantics: str = ''
    id: str = ''  # the topic, filled in by the Composer from the composite's namespace
    framework: str = 'ros2'
    #: An input that gathers samples from several outputs (e.g. a Solver's constraint rows).
    multiple: bool = False

    def with_id(self, topic: str) -> 'PortSpec':
        return replace(self, id=topic)

    @property
    def msg_type_name(self) -> str:
        module = self.msg_type.__module__.split('.')[0]
        return f'{module}/msg/{self.msg_type.__name__}'


class SemanticMismatch(ValueError):
    """Two ports that a connection joins disagree on their metadata."""


def check_connection(source: PortSpec, target: PortSpec, *, source_name: str, target_name: str) -> None:
    """Raise :class:`SemanticMismatch` naming both ports unless ``source`` may feed ``target``."""
    problems = []
    if source.direction != 'output':
        problems.append(f'{source_name} is an {source.direction}, not an output')
    if target.direction != 'input':
        problems.append(f'{target_name} is an {target.direction}, not an input')
    if source.msg_type is not target.msg_type:
        problems.append(f'message type {source.msg_type_name} != {target.msg_type_name}')
    if source.type != target.type:
        problems.append(f"type '{source.type}' != '{target.type}'")
    if _normalise(source.semantics) != _normalise(target.semantics):
        problems.append(f"semantics '{source.semantics}' != '{target.semantics}'")
    if source.framework != target.framework:
        problems.append(f"framework '{source.framework}' != '{target.framework}'")
    if problems:
        raise SemanticMismatch(
            f'refused connection {source_name} -> {target_name}: ' + '; '.join(problems))


def _normalise(semantics: str) -> str:
    return ''.join(semantics.split())


class LocalBus:
    """The outputs living in one process, by topic: the in-process fast path. There is one per ROS
    context (the process's runtime, :class:`~itasc_core.composition.deployment.Runtime`, holds it
    as ``bus``): two contexts in one interpreter (a test's, a replay's) never link each other's ports.

    Outputs built off the tick path for a run-time re-composition (:meth:`deferred`) are not
    registered when they are created: the Composer registers them when it switches to them."""

    _buses: 'weakref.WeakKeyDictionary[Context, LocalBus]' = weakref.WeakKeyDictionary()
    _deferring = threading.local()

    def __init__(self) -> None:
        self._outputs: dict[str, OutputPort] = {}
        self._watchers: list[Callable[[OutputPort], None]] = []
        #: The DDS readers of remote topics, by (topic, message type, composite namespace).
        self._readers: dict[tuple[str, type, str], _RemoteReader] = {}
        self._readers_lock = threading.Lock()
        #: Remote topics whose samples the trigger of this process's composite carries (:mod:`.trigger`).
        self._carried: set[str] = set()
        #: Namespaces of the composites switched off (their readers do not count as listening).
        self.idle: frozenset[str] = frozenset()
        #: Namespaces of the composites in other processes that this process commanded to stop: what
        #: they wrote stops coming on purpose.
        self.stopping: frozenset[str] = frozenset()

    @classmethod
    def of(cls, context: Context) -> 'LocalBus':
        """The bus of the process whose ROS context is ``context``."""
        bus = cls._buses.get(context)
        if bus is None:
            bus = cls._buses[context] = cls()
        return bus

    def watch(self, watcher: Callable[['OutputPort'], None]) -> Callable[[], None]:
        """Call ``watcher(port)`` for every output registered from now on; returns what ends it."""
        self._watchers.append(watcher)
        return lambda: self._watchers.remove(watcher) if watcher in self._watchers else None

    @classmethod
    @contextmanager
    def deferred(cls) -> Iterator[list['OutputPort']]:
        """Within the block, outputs this thread creates are collected in the list yielded instead
        of being registered (the Composer registers them when it switches to them)."""
        ports: list[OutputPort] = []
        cls._deferring.ports = ports
        try:
            yield ports
        finally:
            cls._deferring.ports = None

    def set_idle(self, namespace: str, idle: bool) -> None:
        """The composite of ``namespace`` (and what it holds) is switched off (``idle``) or on: every
        output of the process looks again at who listens before its next send."""
        changed = self.idle | {namespace} if idle else self.idle - {namespace}
        if changed != self.idle:
            self.idle = changed
            for port in self._outputs.values():
                port.recheck()

    def set_stopping(self, namespace: str, stopping: bool) -> None:
        """The composite of ``namespace``, in another process, was commanded to stop (or started anew)."""
        self.stopping = self.stopping | {namespace} if stopping else self.stopping - {namespace}

    def replace(self, port: 'OutputPort') -> None:
        """Register ``port`` in place of the output of its topic, whose in-process links and taps it
        took over (:meth:`OutputPort.take_over`)."""
        self._outputs[port.topic] = port

    def register(self, port: 'OutputPort') -> None:
        pending = getattr(self._deferring, 'ports', None)
        if pending is not None:
            pending.append(port)
            return
        self._outputs[port.topic] = port
        for watcher in list(self._watchers):
            watcher(port)

    def unregister(self, port: 'OutputPort') -> None:
        if self._outputs.get(port.topic) is port:
            del self._outputs[port.topic]

    def lookup(self, topic: str) -> 'OutputPort | None':
        return self._outputs.get(topic)

    def outputs(self) -> list['OutputPort']:
        """The outputs living in this process now."""
        return list(self._outputs.values())

    def read_remote(self, topic: str, port: 'InputPort') -> '_RemoteReader':
        """The reader of ``topic`` (published in another process) that hands its samples to
        ``port`` too: the one the inputs of ``port``'s composite already read it with, or a new one
        (with no DDS subscription if the trigger carries the topic's samples)."""
        key = (topic, port.spec.msg_type, port._node.get_namespace())
        with self._readers_lock:
            reader = self._readers.get(key)
            if reader is None:
                reader = self._readers[key] = _RemoteReader(topic, port, gone=lambda: self._readers.pop(key, None),
                                                            carried=topic in self._carried)
            else:
                reader.join(port)
            return reader

    def carry(self, topic: str) -> None:
        """The trigger of this process's composite carries the samples of ``topic`` from now on
        (its parent's process publishes it): its readers here take them from there, not from DDS."""
        with self._readers_lock:
            self._carried.add(topic)
            for (reader_topic, _, _), reader in self._readers.items():
                if reader_topic == topic:
                    reader.carry()

    def deliver_carried(self, topic: str, data: bytes) -> None:
        """Hand a sample a trigger carried (its CDR bytes) to the inputs that read ``topic``."""
        for (reader_topic, _, _), reader in list(self._readers.items()):
            if reader_topic == topic:
                reader.take(data)

    def stop_reading(self, reader: '_RemoteReader', port: 'InputPort') -> None:
        """``port`` takes no more samples from ``reader`` (which goes with its last port)."""
        with self._readers_lock:
            reader.leave(port)


#: The namespace the ROS graph gives an endpoint whose node it does not know yet (rmw_dds_common).
UNKNOWN_NAMESPACE = '_NODE_NAMESPACE_UNKNOWN_'


class ListenedPublisher:
    """A publisher that sends a sample, as its CDR bytes, only while a DDS reader listens (a
    publish with a reader costs a Fast DDS send in the publishing thread); who listens is looked
    up every :attr:`RECHECK_PERIOD` seconds. A reader of a composite switched off (``idle``,
    namespaces) does not listen."""

    #: How often the number of DDS subscribers is looked up again (seconds).
    RECHECK_PERIOD = 0.2

    def __init__(self, node: Node, msg_type: type, topic: str, qos,
                 idle: Callable[[], frozenset[str]] = frozenset) -> None:
        self.publisher = node.create_publisher(msg_type, topic, qos)
        self._node, self._topic, self._idle = node, topic, idle
        self._listened = False
        self._checked_at = -float('inf')
        #: The reader count and idle composites the last look at the readers' namespaces was for.
        self._looked_for: tuple[int, frozenset[str]] | None = None

    def recheck(self) -> None:
        """Look at who listens before the next send."""
        self._checked_at = -float('inf')

    def _listening(self) -> bool:
        count, idle = self.publisher.get_subscription_count(), self._idle()
        if not count or not idle:
            return count > 0
        if self._looked_for != (count, idle):  # a graph query: only when readers or idle composites changed
            readers = self._node.get_subscriptions_info_by_topic(self._topic)
            self._listened = any(
                not any(info.node_namespace == ns or info.node_namespace.startswith(ns + '/') for ns in idle)
                for info in readers)
            # A reader whose node DDS has not told of yet (a loaded machine) has no namespace: it
            # listens until it has one, looked up again at the next recheck.
            known = len(readers) == count and all(info.node_namespace != UNKNOWN_NAMESPACE for info in readers)
            self._looked_for = (count, idle) if known else None
        return self._listened

    def publish(self, sample: Any, now: float | None = None) -> float:
        """Send ``sample`` if a reader listens (``now``: ``time.monotonic()``, if the caller has it).
        Returns until when (``time.monotonic()``) a publish would send nothing: no reader listened at
        this look and the next is not due (-inf while one listens)."""
        if now is None:
            now = time.monotonic()
        if now - self._checked_at > self.RECHECK_PERIOD:
            self._checked_at = now
            self._listened = self._listening()
        if self._listened:
            self.publisher.publish(serialize(sample))
            return -float('inf')
        return self._checked_at + self.RECHECK_PERIOD


class OutputPort:
    """Writes samples to linked in-process inputs and taps and, when a DDS reader listens, its
    message to DDS."""

    def __init__(self, node: Node, spec: PortSpec) -> None:
        self.spec = spec
        self.topic = spec.id
        self._node = node
        self._bus = LocalBus.of(node.context)
        self._dds = ListenedPublisher(node, spec.msg_type, spec.id, DATA_QOS, idle=lambda: self._bus.idle)
        self._sinks: list[InputPort] = []
        self._taps: list[Callable[[str, Any], None]] = []
        self.last: Any = None
        self._msg_type = spec.msg_type
        #: Until then no DDS reader listens (what the DDS side last returned): a write skips it.
        self._quiet_until = -float('inf')
        self._bus.register(self)

    def link(self, sink: 'InputPort') -> None:
        if sink not in self._sinks:
            self._sinks.append(sink)

    def unlink(self, sink: 'InputPort') -> None:
        if sink in self._sinks:
            self._sinks.remove(sink)

    def tap(self, tap: Callable[[str, Any], None]) -> None:
        """Hand every sample written from now on to ``tap(topic, sample)`` too (in the writing
        thread, in the tick: a tap only keeps the sample)."""
        self._taps.append(tap)

    def untap(self, tap: Callable[[str, Any], None]) -> None:
        if tap in self._taps:
            self._taps.remove(tap)

    def take_over(self, old: 'OutputPort') -> None:
        """Feed the in-process inputs and taps ``old`` fed, and be the output of the topic from now
        on (a swapped entity's port; its topic is the same)."""
        for sink in old._sinks:
            sink.relink(old, self)
        self._sinks, old._sinks = old._sinks + [s for s in self._sinks if s not in old._sinks], []
        self._taps, old._taps = old._taps + [t for t in self._taps if t not in old._taps], []
        self.last = old.last
        self._bus.replace(self)

    def recheck(self) -> None:
        """Look at who listens over DDS before the next send (:meth:`LocalBus.set_idle`)."""
        self._dds.recheck()
        self._quiet_until = -float('inf')

    @property
    def last_message(self) -> Any:
        """The newest sample as its ROS message (None before the first)."""
        return None if self.last is None else as_message(self.last)

    def write(self, sample: Any) -> None:
        """Write a sample (or its ROS message, turned into the sample)."""
        if type(sample) is self._msg_type:
            sample = as_sample(sample)
        self.last = sample
        now = time.monotonic()  # one reading for the sinks' arrival and the DDS side's recheck
        topic = self.topic
        for sink in self._sinks:
            sink.deliver(sample, topic, now)
        for tap in self._taps:
            tap(topic, sample)
        if now > self._quiet_until:  # most outputs have no DDS reader: no call for them
            self._quiet_until = self._dds.publish(sample, now)

    def destroy(self) -> None:
        self._bus.unregister(self)
        self._sinks.clear()
        self._taps.clear()
        self._node.destroy_publisher(self._dds.publisher)


class _RemoteReader:
    """The one DDS reader of a topic published in another process, for every input port of a
    composite that reads it: each reader takes and converts every sample (two Monitors of the
    program composite reading a Task process's state did it twice a tick, ~100 us of CPU each).
    It is a subscription of one of those ports' nodes; when that port leaves, the next one's node
    subscribes before the old subscription goes (no sample is missed). A topic whose samples the
    process's trigger carries (``carried``, :meth:`LocalBus.carry`) needs no subscription: the
    Scheduler hands the reader each sample (:meth:`take`)."""

    def __init__(self, topic: str, port: 'InputPort', *, gone: Callable[[], object], carried: bool = False) -> None:
        self.topic = topic
        self.ports: tuple[InputPort, ...] = (port,)
        self._gone = gone
        self._msg_type = port.spec.msg_type
        self._to_sample, self._raw = received_as_sample(self._msg_type)  # CDR bytes: no ROS message built
        self._carried = carried
        self._subscription = self._subscribe(port)

    def _subscribe(self, port: 'InputPort') -> tuple['InputPort', Any]:
        if self._carried:
            return port, None
        return port, port._node.create_subscription(self._msg_type, self.topic, self._received,
                                                    DATA_READER_QOS, raw=self._raw)

    def _received(self, received: Any) -> None:
        sample = self._to_sample(received)
        for port in self.ports:
            port.deliver(sample, self.topic)

    def carry(self) -> None:
        """The trigger carries the samples from now on: no DDS subscription."""
        self._carried = True
        owner, subscription = self._subscription
        self._subscription = owner, None
        if subscription is not None:
            owner._node.destroy_subscription(subscription)

    def take(self, data: bytes) -> None:
        """A sample the trigger carried, as its CDR bytes."""
        self._received(data if self._raw else deserialize_message(data, self._msg_type))

    def join(self, port: 'InputPort') -> None:
        self.ports += (port,)

    def leave(self, port: 'InputPort') -> None:
        self.ports = tuple(p for p in self.ports if p is not port)
        owner, subscription = self._subscription
        if owner is not port:
            return
        if self.ports:
            self._subscription = self._subscribe(self.ports[0])
        else:
            self._gone()
        if subscription is not None:
            owner._node.destroy_subscription(subscription)


class InputPort:
    """Receives samples from one output (or several, for ``multiple`` inputs)."""

    def __init__(self, node: Node, spec: PortSpec, *, on_sample: Callable[[Any], None] | None = None) -> None:
        self.spec = spec
        self._node = node
        self._on_sample = on_sample
        self._links: list[OutputPort] = []
        self._readers: dict[str, _RemoteReader] = {}
        self.sources: list[str] = []
        #: The sources whose output lives in another process: their samples cross DDS and come
        #: later than those of the same tick (at times a tick or more).
        self.remote: set[str] = set()
        self._bus = LocalBus.of(node.context)
        self._msg_type, self._multiple = spec.msg_type, spec.multiple
        self.latest: Any = None
        #: For ``multiple`` inputs: the newest sample of every source topic.
        self.samples: dict[str, Any] = {}
        #: For ``multiple`` inputs: what came from each source in another process since the entity took it.
        self._arrived: dict[str, deque[Any]] = {}
        self.received = 0
        #: When the newest sample arrived (``time.monotonic()``), None before the first.
        self.received_at: float | None = None

    @property
    def connected(self) -> bool:
        return bool(self.sources)

    def connect(self, topic: str) -> None:
        """Connect to the output publishing on ``topic``: in-process if it lives here, else DDS."""
        if topic in self.sources:
            return
        self.sources.append(topic)
        output = self._bus.lookup(topic)
        if output is not None:
            output.link(self)
            self._links.append(output)
        else:
            self._readers[topic] = self._bus.read_remote(topic, self)
            self.remote.add(topic)

    def relink(self, old: OutputPort, new: OutputPort) -> None:
        """The output this input is linked to was replaced (see :meth:`OutputPort.take_over`)."""
        self._links = [new if link is old else link for link in self._links]

    def take_over(self, old: 'InputPort') -> None:
        """Start from the samples ``old`` last received (a swapped entity computes at its first
        tick, before any new sample came)."""
        self.latest, self.received, self.received_at = old.latest, old.received, old.received_at
        self.samples = dict(old.samples)

    def disconnect_from(self, topic: str) -> None:
        """Stop receiving from the output on ``topic`` (a removed entity's), and forget its sample."""
        if topic not in self.sources:
            return
        self.sources.remove(topic)
        self.remote.discard(topic)
        self.samples.pop(topic, None)
        self._arrived.pop(topic, None)
        for output in [o for o in self._links if o.topic == topic]:
            output.unlink(self)
            self._links.remove(output)
        reader = self._readers.pop(topic, None)
        if reader is not None:
            self._bus.stop_reading(reader, self)

    def switched_off(self, topic: str) -> bool:
        """Whether ``topic`` is read over DDS from a composite that this process has switched off
        (:meth:`LocalBus.set_idle`): what came from there was written before, and holds no more."""
        return self._remote_from(topic, self._bus.idle)

    def stopping(self, topic: str) -> bool:
        """Whether ``topic`` is read over DDS from a composite that this process commanded to stop
        (:meth:`LocalBus.set_stopping`): its samples stop coming on purpose."""
        return self._remote_from(topic, self._bus.stopping)

    def _remote_from(self, topic: str, namespaces: frozenset[str]) -> bool:
        """Whether ``topic`` is read over DDS from a composite of one of ``namespaces``."""
        return topic in self.remote and any(topic.startswith(namespace + '/') for namespace in namespaces)

    def deliver(self, msg: Any, topic: str, now: float | None = None) -> None:
        """Take a sample (or its ROS message, turned into the sample) from ``topic``, arrived
        ``now`` (``time.monotonic()``; read here if not given)."""
        if type(msg) is self._msg_type:
            msg = as_sample(msg)
        self.latest = msg
        self.received += 1
        self.received_at = time.monotonic() if now is None else now
        if self._multiple:
            self.samples[topic] = msg
            if topic in self.remote:
                self._arrived.setdefault(topic, deque(maxlen=ARRIVED)).append(msg)
        if self._on_sample is not None:
            self._on_sample(msg)

    def take_arrived(self, topic: str) -> list[Any]:
        """For a ``multiple`` input: the samples from ``topic`` (read over DDS) that came since the
        last call, oldest first (at most the newest ``ARRIVED``). Two can come between two ticks of a
        process that was busy, and :attr:`samples` holds only the newer."""
        arrived = self._arrived.get(topic)
        if not arrived:
            return []
        taken = list(arrived)
        arrived.clear()
        return taken

    def disconnect(self) -> None:
        for output in self._links:
            output.unlink(self)
        for reader in self._readers.values():
            self._bus.stop_reading(reader, self)
        self._links.clear()
        self._readers.clear()
        self.sources.clear()
        self.remote.clear()
        self.samples.clear()
        self._arrived.clear()

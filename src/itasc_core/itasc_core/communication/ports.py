"""Data-flow ports with metadata (paper §4.3 Listing 1, §7).

A port carries the paper's metadata: ``type`` (what general kind of data), ``msg_type`` (the
platform type, here a ROS 2 message class), ``semantics`` (the geometric semantics, e.g.
``Pose(ee|base)@base``), ``id`` (the topic), ``direction`` and ``framework``. The Composer checks
that connected ports agree on all of it before connecting them.

Locality is a deployment choice: an input whose output lives in the same process is linked to it
directly (the message object is handed over, no serialisation, no executor hop); otherwise it
subscribes to the output's topic over DDS. An output publishes on DDS only while someone outside
the process listens (another process, a recorder), so co-located connections pay for nothing
they do not need.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Any, Callable

from rclpy.node import Node

from .qos import DATA_QOS

__all__ = [
    'PortSpec',
    'InputPort',
    'OutputPort',
    'LocalBus',
    'SemanticMismatch',
    'check_connection',
]


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
    """The outputs living in this process, by topic: the in-process fast path."""

    _outputs: dict[str, 'OutputPort'] = {}

    @classmethod
    def register(cls, port: 'OutputPort') -> None:
        cls._outputs[port.topic] = port

    @classmethod
    def unregister(cls, port: 'OutputPort') -> None:
        if cls._outputs.get(port.topic) is port:
            del cls._outputs[port.topic]

    @classmethod
    def lookup(cls, topic: str) -> 'OutputPort | None':
        return cls._outputs.get(topic)


class OutputPort:
    """Writes samples to linked in-process inputs and, when someone else listens, to DDS."""

    #: How often the number of DDS subscribers is looked up again (seconds).
    RECHECK_PERIOD = 0.2

    def __init__(self, node: Node, spec: PortSpec) -> None:
        self.spec = spec
        self.topic = spec.id
        self._node = node
        self._publisher = node.create_publisher(spec.msg_type, spec.id, DATA_QOS)
        self._sinks: list[InputPort] = []
        self._remote = False
        self._checked_at = 0.0
        self.last: Any = None
        LocalBus.register(self)

    def link(self, sink: 'InputPort') -> None:
        if sink not in self._sinks:
            self._sinks.append(sink)

    def unlink(self, sink: 'InputPort') -> None:
        if sink in self._sinks:
            self._sinks.remove(sink)

    def write(self, msg: Any) -> None:
        self.last = msg
        for sink in self._sinks:
            sink.deliver(msg, self.topic)
        now = time.monotonic()
        if now - self._checked_at > self.RECHECK_PERIOD:
            self._checked_at = now
            self._remote = self._publisher.get_subscription_count() > 0
        if self._remote:
            self._publisher.publish(msg)

    def destroy(self) -> None:
        LocalBus.unregister(self)
        self._sinks.clear()
        self._node.destroy_publisher(self._publisher)


class InputPort:
    """Receives samples from one output (or several, for ``multiple`` inputs)."""

    def __init__(self, node: Node, spec: PortSpec, *, on_sample: Callable[[Any], None] | None = None) -> None:
        self.spec = spec
        self._node = node
        self._on_sample = on_sample
        self._links: list[OutputPort] = []
        self._subscriptions: list = []
        self.sources: list[str] = []
        self.latest: Any = None
        #: For ``multiple`` inputs: the newest sample of every source topic.
        self.samples: dict[str, Any] = {}
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
        output = LocalBus.lookup(topic)
        if output is not None:
            output.link(self)
            self._links.append(output)
        else:
            self._subscriptions.append(self._node.create_subscription(
                self.spec.msg_type, topic, lambda msg, topic=topic: self.deliver(msg, topic), DATA_QOS))

    def deliver(self, msg: Any, topic: str) -> None:
        self.latest = msg
        self.received += 1
        self.received_at = time.monotonic()
        if self.spec.multiple:
            self.samples[topic] = msg
        if self._on_sample is not None:
            self._on_sample(msg)

    def disconnect(self) -> None:
        for output in self._links:
            output.unlink(self)
        for subscription in self._subscriptions:
            self._node.destroy_subscription(subscription)
        self._links.clear()
        self._subscriptions.clear()
        self.sources.clear()
        self.samples.clear()

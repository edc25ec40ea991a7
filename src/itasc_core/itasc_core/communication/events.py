"""Event communication (paper §6.2, §7.2): raising events with per-source sequence numbers, and
receiving them without loss into a buffer that the receiver drains at its next update.

Two classes of events: *common* events are buffered and processed at the receiver's next update;
*priority* events (timer and scheduler triggers, ``e_emergency``) are handed over on arrival.
"""

from __future__ import annotations

import functools
import threading
from collections import deque
from typing import Callable, Iterable

from rclpy.node import Node

from itasc_msgs.msg import Event

from .event_hub import EventHub
from .event_names import is_priority
from .qos import EVENT_LISTENER_QOS, EVENT_QOS

__all__ = ['Event', 'EventRaiser', 'EventListener', 'events_topic']


def events_topic(namespace: str) -> str:
    return f'{namespace.rstrip("/")}/events'


class EventRaiser:
    """Publishes events of one source on one composite's event topic: through the writer of the
    process's :class:`~.event_hub.EventHub` if it has one, otherwise through a writer of ``node``'s."""

    def __init__(self, node: Node, *, topic: str, source: str | None = None) -> None:
        self._node = node
        self._source = source or node.get_fully_qualified_name()
        self._hub = EventHub.of(node.context)  # counts what the process raised
        self._publisher = (self._hub.writer(topic) if self._hub is not None
                           else node.create_publisher(Event, topic, EVENT_QOS))
        self._live = True
        self._seq = 0
        self._lock = threading.Lock()
        self.topic = topic

    @property
    def publisher(self):
        return self._publisher

    def raise_event(self, name: str, *, priority: bool = False, detail: str = '') -> Event:
        msg = Event()
        msg.source = self._source
        msg.name = name
        msg.priority = priority or is_priority(name)
        msg.detail = detail
        with self._lock:  # sequence numbers in publication order, whichever thread raises
            self._seq += 1
            msg.seq = self._seq
            msg.stamp = self._node.get_clock().now().to_msg()
            if self._hub is not None:
                self._hub.raising(msg, self.topic)  # before its copy from DDS can arrive
            self._publisher.publish(msg)
            if self._hub is not None:
                self._hub.raised += 1
        return msg

    def destroy(self) -> None:
        """No more events from this raiser (idempotent)."""
        with self._lock:
            live, self._live = self._live, False
        if not live:
            return
        if self._hub is not None:
            self._hub.release(self.topic)
        else:
            self._node.destroy_publisher(self._publisher)


class EventListener:
    """Subscribes to one or more event topics; buffers common events, passes priority ones on.

    With ``immediate``, every accepted event is handed to ``on_priority`` on arrival (for
    entities that are time-triggered themselves, such as a Scheduler waiting to be initialised).
    Sequence numbers are checked per source: a gap is counted in :attr:`lost` and reported through
    ``on_gap`` (it cannot happen with the reliable, keep-all QoS unless a publisher was destroyed
    with events still in flight). ``on_held`` is called when a common event is buffered into an empty
    buffer (the reader wakes up to drain it).

    In a process with an :class:`~.event_hub.EventHub` the listener shares the process's reader of
    each topic; otherwise it subscribes on ``node``. :meth:`destroy` ends the listening (an
    :class:`~itasc_core.entity.Entity` destroys its listeners with itself).
    """

    def __init__(
        self,
        node: Node,
        *,
        topics: Iterable[str],
        on_priority: Callable[[Event], None] | None = None,
        accept: Callable[[str], bool] | None = None,
        on_gap: Callable[[str, int, int], None] | None = None,
        immediate: bool = False,
        on_held: Callable[[], None] | None = None,
    ) -> None:
        self._buffer: deque[Event] = deque()
        self._last_seq: dict[tuple[str, str], int] = {}
        self._on_priority = on_priority
        self._accept = accept
        self._on_gap = on_gap
        self._immediate = immediate
        self._on_held = on_held
        self.lost = 0
        self._node = node
        self._topics = list(topics)
        self._hub = self._gates = EventHub.of(node.context)
        if self._hub is not None:
            for topic in self._topics:
                self._hub.add(topic, self._receive)
            self._subscriptions = []
        else:
            self._subscriptions = [
                node.create_subscription(
                    Event, topic, functools.partial(self._receive, topic=topic), EVENT_LISTENER_QOS)
                for topic in self._topics
            ]

    def destroy(self) -> None:
        """Stop listening (idempotent)."""
        if self._hub is not None:
            for topic in self._topics:
                self._hub.remove(topic, self._receive)
            self._hub = None
        for subscription in self._subscriptions:
            self._node.destroy_subscription(subscription)
        self._subscriptions = []

    def _receive(self, msg: Event, topic: str) -> None:
        key = (msg.source, topic)
        last = self._last_seq.get(key)
        # seq 1 starts a new incarnation of a source (an entity re-created by its Composer); a
        # source first heard of mid-stream raised its earlier events before we existed.
        if last is not None and msg.seq != 1 and msg.seq != last + 1:
            self.lost += max(0, msg.seq - last - 1)
            if self._on_gap is not None:
                self._on_gap(msg.source, last, msg.seq)
        self._last_seq[key] = msg.seq
        if self._accept is not None and not self._accept(msg.name):
            return
        gate = self._gates.gate if self._gates is not None else None
        if gate is not None and gate(self._node, msg, topic, lambda: self._handle(msg)):
            return
        self._handle(msg)

    #: Events buffered by the listeners of this process so far (any thread): while it does not
    #: change, no listener holds an event it did not hold before (the Composers' pass after a tick).
    buffered = 0

    def _handle(self, msg: Event) -> None:
        if (msg.priority or self._immediate) and self._on_priority is not None:
            self._on_priority(msg)
        else:
            self._buffer.append(msg)
            EventListener.buffered += 1
            if self._on_held is not None and len(self._buffer) == 1:  # the reader drains all it holds
                self._on_held()

    def drain(self) -> list[Event]:
        """Take every buffered event, oldest first (paper §7.2: empty the buffer on each read)."""
        if not self._buffer:
            return []  # the usual case, read every tick
        events = list(self._buffer)
        self._buffer.clear()
        return events

    def __len__(self) -> int:
        return len(self._buffer)

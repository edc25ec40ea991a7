"""One DDS reader per event topic in a process (paper §7.2: events reach every entity of a
composite without loss).

Every entity of a composite listens to the composite's event topic. With one DDS reader per
entity, a process hosting a composite of twenty entities takes, deserializes and dispatches every
event twenty times: at thousands of events per second the Python callbacks alone exceed a core,
the readers fall behind and the reliable writers of the whole application block. An
:class:`EventHub` owns one reader per event topic and hands each event, in arrival order, to
every listener of that topic in the process. Events still travel over DDS: anyone outside the
process (a recorder, ``ros2 topic echo``, a composite in another process) sees all of them.

An event raised in the process reaches the process's listeners without the round trip through
DDS (issue #9: a Monitor's event acted on before the next tick): the raiser hands it to the hub,
which delivers it at the next :meth:`EventHub.flush` (the Timer's, after each tick) or before the
next event that arrives over DDS, whichever comes first, and drops its copy coming back from DDS.
Delivery is run to completion: an event raised by a listener while events are delivered waits
until the one being delivered has reached every listener.

The hub also owns the process's one writer per event topic, shared by all its raisers (the event
names its source): every DDS endpoint of a process costs every later one of the process (Fast DDS
pairs each new endpoint with every local one of the other kind), and a writer per entity made a
program's bring-up grow faster than its number of Tasks.

The owner of a process's executor installs the hub (:meth:`EventHub.install`, done by
:class:`~itasc_core.composition.deployment.Runtime`); an :class:`~.events.EventListener`
created in a context without a hub subscribes on its own node as before.
"""

from __future__ import annotations

import functools
import threading
import weakref
from collections import deque
from typing import Callable

from rclpy.context import Context
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.subscription import Subscription

from itasc_msgs.msg import Event

from .process_writers import process_node
from .qos import EVENT_LISTENER_QOS, EVENT_QOS

__all__ = ['EventHub']

Receiver = Callable[[Event, str], None]
#: ``gate(node, event, topic, handle)``: see :attr:`EventHub.gate`.
Gate = Callable[[Node, Event, str, Callable[[], None]], bool]


class EventHub:
    """The event readers of one ROS context (one process), shared by all its listeners."""

    _hubs: 'weakref.WeakKeyDictionary[Context, EventHub]' = weakref.WeakKeyDictionary()

    def __init__(self, node: Node) -> None:
        self._node = node
        self._subscriptions: dict[str, Subscription] = {}
        #: by topic, in registration order (a dict: membership is checked per event and receiver)
        self._receivers: dict[str, dict[Receiver, None]] = {}
        #: Replay seam (:mod:`itasc_bringup.replay`): when set, every event a listener of this process
        #: accepts is first offered to ``gate(node, msg, topic, handle)`` (``node`` owns the listener);
        #: a gate that returns True holds the event and calls ``handle()`` when it is due. None: events
        #: are handled on arrival.
        self.gate: Gate | None = None
        #: How many events this process's raisers raised (replay seam: while it does not change,
        #: nothing new can be waiting on the process's event topics).
        self.raised = 0
        #: Events raised in this process, not yet delivered to its listeners.
        self._local: deque[tuple[Event, str]] = deque()
        #: Those delivered or to deliver here, whose copy from DDS is to be dropped: (topic, source, seq, stamp)
        self._echoes: set[tuple] = set()
        self._echoes_lock = threading.Lock()  # raisers of other threads add to it
        self._delivering = False
        #: by topic: the shared writer and how many raisers use it
        self._writers: dict[str, tuple[Publisher, int]] = {}
        self._writers_lock = threading.Lock()  # raisers are created and destroyed off the tick path too

    #: The hub's node: hidden (``ros2 node list -a`` shows it), in the namespace of the composite
    #: the process was started for, where a parent's Composer looks for it.
    NODE_NAME = '_event_hub'

    @classmethod
    def install(cls, executor, *, namespace: str = '/') -> 'EventHub':
        """Give ``executor``'s context a hub, on a hidden node in ``namespace`` spun by ``executor``."""
        hub = cls._hubs.get(executor.context)
        if hub is None:
            hub = cls._hubs[executor.context] = cls(process_node(executor, name=cls.NODE_NAME, namespace=namespace))
        return hub

    @classmethod
    def of(cls, context: Context) -> 'EventHub | None':
        """The hub of ``context``, if its process installed one."""
        return cls._hubs.get(context)

    def add(self, topic: str, receiver: Receiver) -> None:
        """Hand every event arriving on ``topic`` from now on to ``receiver(event, topic)``."""
        if topic not in self._subscriptions:
            self._receivers[topic] = {}
            self._subscriptions[topic] = self._node.create_subscription(
                Event, topic, functools.partial(self._dispatch, topic=topic), EVENT_LISTENER_QOS)
        self._receivers[topic][receiver] = None

    def remove(self, topic: str, receiver: Receiver) -> None:
        """Stop handing ``topic``'s events to ``receiver``; the last one gone, the reader goes too."""
        receivers = self._receivers.get(topic, {})
        receivers.pop(receiver, None)
        if not receivers and topic in self._subscriptions:
            self._node.destroy_subscription(self._subscriptions.pop(topic))
            del self._receivers[topic]
            with self._echoes_lock:  # no copy will come
                self._echoes = {echo for echo in self._echoes if echo[0] != topic}

    def writer(self, topic: str) -> Publisher:
        """The process's writer of ``topic``'s events (:meth:`release` it once per call)."""
        with self._writers_lock:
            publisher, users = self._writers.get(topic, (None, 0))
            if publisher is None:
                publisher = self._node.create_publisher(Event, topic, EVENT_QOS)
            self._writers[topic] = (publisher, users + 1)
            return publisher

    def release(self, topic: str) -> None:
        """A raiser of ``topic`` is gone; the last one gone, the writer leaves the graph too."""
        with self._writers_lock:
            publisher, users = self._writers.pop(topic)
            if users > 1:
                self._writers[topic] = (publisher, users - 1)
                return
        self._node.destroy_publisher(publisher)

    def raising(self, msg: Event, topic: str) -> None:
        """``msg`` is about to be published on ``topic`` by a raiser of this process (any thread):
        deliver it here at the next flush, and drop its copy from DDS."""
        if topic in self._receivers:
            with self._echoes_lock:
                self._echoes.add(_echo(msg, topic))
            self._local.append((msg, topic))

    def flush(self) -> None:
        """Deliver the events raised in this process so far, and those their listeners raise (call
        it on the executor's thread, between computations)."""
        if self._delivering or not self._local:
            return  # the delivery under way takes them, in order
        self._delivering = True
        try:
            while self._local:
                self._deliver(*self._local.popleft())
        finally:
            self._delivering = False

    def _dispatch(self, msg: Event, topic: str) -> None:
        self.flush()  # what this process raised before this event arrived
        echo = _echo(msg, topic)
        with self._echoes_lock:
            ours = echo in self._echoes
            self._echoes.discard(echo)
        if ours:
            return
        delivering, self._delivering = self._delivering, True
        try:
            self._deliver(msg, topic)
        finally:
            self._delivering = delivering
        self.flush()  # what its listeners raised on it

    def _deliver(self, msg: Event, topic: str) -> None:
        # a copy: a receiver may create or destroy entities (and their listeners) on an event
        receivers = self._receivers.get(topic, {})
        for receiver in list(receivers):
            if receiver in receivers:
                receiver(msg, topic)


def _echo(msg: Event, topic: str) -> tuple:
    return topic, msg.source, msg.seq, msg.stamp.sec, msg.stamp.nanosec

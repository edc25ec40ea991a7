"""The common base of every entity of the Composition Pattern (paper §3.1, Fig. 1).

Every entity is an rclpy node living in the namespace of its composite and raising events on that
composite's event topic. The boundary of knowledge (§3.1) is what an entity is given here: the
name and topics of its own composite, nothing else.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import wraps
from typing import Any, Callable

from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.subscription import Subscription
from rclpy.utilities import get_default_context

from .communication import call_sites
from .communication.events import EventListener, EventRaiser, events_topic
from .communication.process_writers import PARAMETER_EVENTS, ProcessWriters, serving_nothing
from .pace import PACE

__all__ = ['CompositeContext', 'Entity']


@dataclass(frozen=True)
class CompositeContext:
    """What an entity knows of the composite it belongs to."""

    name: str
    namespace: str
    parent_namespace: str | None = None

    @property
    def events_topic(self) -> str:
        return events_topic(self.namespace)

    @property
    def parent_events_topic(self) -> str:
        return events_topic(self.parent_namespace or self.namespace)

    @property
    def state_topic(self) -> str:
        return f'{self.namespace}/state'

    @property
    def trigger_topic(self) -> str:
        return f'{self.namespace}/trigger'

    def child(self, name: str) -> 'CompositeContext':
        return CompositeContext(name=name, namespace=f'{self.namespace}/{name}', parent_namespace=self.namespace)


def _paced(call: Callable) -> Callable:
    """``call`` (a method of rclpy's Node that creates or destroys an endpoint), made in a gap
    between ticks when the calling thread is paced (:mod:`.pace`)."""
    @wraps(call)
    def paced(self, *args, **kwargs):
        PACE.gap()
        return call(self, *args, **kwargs)
    return paced


class Entity(Node):
    """An rclpy node that belongs to a composite and raises events on its event topic.

    No entity offers rclpy's six parameter services: each node's six are twelve DDS endpoints that
    every later endpoint of the process is matched against, which made bring-up grow with the
    square of the number of Tasks. The Configurator of each composite serves its entities'
    parameters instead (:mod:`.configuration.parameter_service`). For the same reason an entity
    logs to ``/rosout`` and announces its parameter changes on ``/parameter_events`` through its
    process's writers (:mod:`.communication.process_writers`), when the process has them. Its log
    calls find their call site without ``inspect`` (:mod:`.communication.call_sites`): one may come
    from a tick.
    """

    def __init__(self, name: str, *, composite: CompositeContext) -> None:
        PACE.gap()
        call_sites.install()
        writers = ProcessWriters.of(get_default_context())
        logs_there = writers if writers is not None and writers.logs(composite.namespace) else None
        super().__init__(name, namespace=composite.namespace, enable_rosout=logs_there is None, **serving_nothing())
        #: held while the node lives: its log lines go out on the process's ``/rosout`` writer
        self._rosout = None if logs_there is None else logs_there.rosout(self.get_logger().name)
        self.composite = composite
        self.entity_name = name
        self._raisers: list[EventRaiser] = []
        self._raiser = self.raiser(topic=composite.events_topic)
        self._listeners: list[EventListener] = []

    _create_publisher = _paced(Node.create_publisher)

    def create_publisher(self, msg_type: Any, topic: str, *args, **kwargs) -> Publisher:
        """rclpy's, but ``/parameter_events`` (rclpy's Node makes one for itself) is the process's."""
        if topic == PARAMETER_EVENTS and (writers := ProcessWriters.of(self.context)) is not None:
            return writers.parameter_events
        return self._create_publisher(msg_type, topic, *args, **kwargs)

    create_subscription = _paced(Node.create_subscription)
    create_service = _paced(Node.create_service)
    create_client = _paced(Node.create_client)
    destroy_publisher = _paced(Node.destroy_publisher)
    destroy_subscription = _paced(Node.destroy_subscription)
    destroy_service = _paced(Node.destroy_service)
    destroy_client = _paced(Node.destroy_client)

    # A reconfiguration makes every new endpoint it needs before it lets go of any old one
    # (:meth:`let_go`): a topic name rclpy refuses then leaves the entity with the endpoints it had,
    # and it can take its old parameters back.

    def subscription_for(self, current: Subscription | None, msg_type: Any, topic: str, callback: Callable,
                         qos: Any) -> Subscription:
        """``current`` if it subscribes ``msg_type`` on ``topic`` already, else a new subscription."""
        if current is not None and current.topic_name == topic and current.msg_type is msg_type:
            return current
        return self.create_subscription(msg_type, topic, callback, qos)

    def publisher_for(self, current: Publisher | None, msg_type: Any, topic: str, qos: Any) -> Publisher:
        """``current`` if it publishes ``msg_type`` on ``topic`` already, else a new publisher."""
        if current is not None and current.topic_name == topic and current.msg_type is msg_type:
            return current
        return self.create_publisher(msg_type, topic, qos)

    def let_go(self, old: Subscription | Publisher | None, *, kept: Subscription | Publisher | None) -> None:
        """Destroy ``old`` unless it is the endpoint ``kept``."""
        if old is None or old is kept:
            return
        if isinstance(old, Subscription):
            self.destroy_subscription(old)
        else:
            self.destroy_publisher(old)

    def raiser(self, *, topic: str, source: str | None = None) -> EventRaiser:
        """An :class:`EventRaiser` of this entity's on ``topic``, destroyed with it."""
        raiser = EventRaiser(self, topic=topic, source=source)
        self._raisers.append(raiser)
        return raiser

    def destroy_raiser(self, raiser: EventRaiser) -> None:
        """No more events from ``raiser`` (one of :meth:`raiser`'s), and this entity lets go of it."""
        raiser.destroy()
        if raiser in self._raisers:
            self._raisers.remove(raiser)

    def listen(self, **listener_kwargs) -> EventListener:
        """An :class:`EventListener` of this entity's, destroyed with it."""
        listener = EventListener(self, **listener_kwargs)
        self._listeners.append(listener)
        return listener

    def raise_event(self, name: str, *, priority: bool = False, detail: str = '') -> None:
        self._raiser.raise_event(name, priority=priority, detail=detail)

    def detach(self) -> None:
        """Stop listening to events (before the node is destroyed)."""
        for listener in self._listeners:
            listener.destroy()
        self._listeners.clear()

    def destroy_node(self) -> None:
        self.detach()
        for raiser in self._raisers:
            raiser.destroy()
        super().destroy_node()
        self._rosout = None

"""Observing data-flow topics without costing the control loop a DDS send (issue #9).

Every DDS reader of a topic the tick publishes makes the tick pay for the publish: the message
built from its sample, serialised and sent by Fast DDS in the publishing thread (0.2-0.6 ms per
publish on a loaded two-core machine, ``bench/bench_visualization.py``). So the tools that watch
every sample of a run (the console's summary, the recorder) *tap* the output port when it lives
in this process (:meth:`~itasc_core.communication.ports.OutputPort.tap`: the sample object is
handed over in the tick, nothing else happens there), and read the topic over DDS only when its
publisher lives in another process (``--deploy per-composite``, another host). A DDS reader made
before the port existed (tools start before the hierarchy is deployed, so that they miss no tick
of a composite in another process) is replaced by a tap as soon as the port appears here.

Such a reader is made only for a topic that the deployment puts in another process (``elsewhere``,
from the Runtime's plan): one made for a topic whose output turns up here is destroyed when it is
tapped, but rclpy's EventsExecutor lets it go only when it reaches its entity update, queued behind
the events already waiting; meanwhile every output with such a reader publishes it every tick. With
``--deploy single --record --between-ticks spin`` at 1 kHz (a thread that serves the executor an event
every 2 ms) the ~30 outputs' samples kept that update from ever being reached: the readers stayed, the
bootstrap's DDS receiving thread took 71 % of a core, and the run went at 277-304 Hz.
"""

from __future__ import annotations

from typing import Any, Callable

from rclpy.node import Node
from rclpy.qos import QoSProfile

from itasc_core.communication.cdr import received_as_sample
from itasc_core.communication.ports import LocalBus, OutputPort

__all__ = ['Observer']

Callback = Callable[[str, Any], None]


class Observer:
    """Hands every sample of the observed local outputs to their callback, ``callback(topic,
    sample)``, from a tap in the tick; a topic whose output is not (yet) in this process and that
    ``elsewhere(topic)`` says lives in another one is read by the DDS reader its ``subscribe()``
    makes, replaced by the tap should the output appear here (``elsewhere``: every topic, unless
    told)."""

    def __init__(self, node: Node, *, elsewhere: Callable[[str], bool] = lambda topic: True) -> None:
        self._node = node
        self._elsewhere = elsewhere
        self._wanted: dict[str, Callback] = {}
        self._tapped: dict[str, OutputPort] = {}
        self._readers: dict[str, Any] = {}
        #: Who else gets what a DDS reader made by :meth:`samples` receives (:meth:`share`), by topic.
        self._sharing: dict[str, list[Callback]] = {}
        self._bus = LocalBus.of(node.context)
        #: Told of every output of this process (:meth:`on_output`).
        self._outputs_to: list[Callable[[OutputPort], None]] = []
        self._unwatch = self._bus.watch(self._appeared)

    def observe(self, topic: str, callback: Callback, *, subscribe: Callable[[], Any]) -> None:
        """From now on, every sample of ``topic`` to ``callback`` (tapped), or, while its output
        is not in this process, whatever the subscription ``subscribe()`` makes receives, if it
        lives ``elsewhere``."""
        self._wanted[topic] = callback
        port = self._bus.lookup(topic)
        if port is not None:
            self._tap(port)
        elif self._elsewhere(topic):
            self._readers[topic] = subscribe()

    def samples(self, topic: str, msg_type: type, callback: Callback, *, qos: QoSProfile) -> None:
        """Every sample of ``topic`` to ``callback``: tapped, or over DDS, each message turned into
        its sample (once, for ``callback`` and whoever :meth:`share` s the reader)."""
        to_sample, raw = received_as_sample(msg_type)

        def receive(received: Any) -> None:
            sample = to_sample(received)
            callback(topic, sample)
            for other in self._sharing.get(topic, ()):
                other(topic, sample)

        def subscribe() -> Any:
            self._sharing[topic] = []
            return self._node.create_subscription(msg_type, topic, receive, qos, raw=raw)
        self.observe(topic, callback, subscribe=subscribe)

    def share(self, topic: str, callback: Callback) -> bool:
        """Hand what this observer's DDS reader of ``topic`` (made by :meth:`samples`) receives to
        ``callback`` too, so that another tool of the process needs no reader of its own (each one
        takes and converts every sample of a remote topic, at the tick rate); False if there is no
        such reader."""
        others = self._sharing.get(topic)  # there while the reader is (see _tap and close)
        if others is None:
            return False
        others.append(callback)
        return True

    def drop(self, topic: str) -> None:
        """Observe ``topic`` no more (its reader, if any, is the caller's to destroy)."""
        callback = self._wanted.pop(topic, None)
        port = self._tapped.pop(topic, None)
        if port is not None and callback is not None:
            port.untap(callback)
        self._readers.pop(topic, None)
        self._sharing.pop(topic, None)

    def on_output(self, appeared: Callable[[OutputPort], None]) -> None:
        """Call ``appeared(port)`` for every output of this process: those there now and, as they
        appear, the others (before their first sample)."""
        self._outputs_to.append(appeared)
        for port in self._bus.outputs():
            appeared(port)

    def local(self, topic: str) -> bool:
        """Whether ``topic``'s output is in this process."""
        return self._bus.lookup(topic) is not None

    @property
    def tapped(self) -> set[str]:
        return set(self._tapped)

    def _appeared(self, port: OutputPort) -> None:
        for appeared in self._outputs_to:
            appeared(port)
        if port.topic in self._wanted:
            self._tap(port)

    def _tap(self, port: OutputPort) -> None:
        previous = self._tapped.get(port.topic)
        if previous is port:
            return
        if previous is not None:  # re-composed: a new output on the same topic
            previous.untap(self._wanted[port.topic])
        reader = self._readers.pop(port.topic, None)
        if reader is not None:
            self._node.destroy_subscription(reader)
            self._sharing.pop(port.topic, None)  # those read the output port itself now
        port.tap(self._wanted[port.topic])
        self._tapped[port.topic] = port

    def close(self) -> None:
        """Tap nothing more (the DDS readers go with the node)."""
        self._unwatch()
        self._outputs_to.clear()
        for topic, port in self._tapped.items():
            port.untap(self._wanted[topic])
        self._tapped.clear()
        self._wanted.clear()
        self._sharing.clear()

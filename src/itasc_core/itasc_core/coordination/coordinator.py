"""The Coordinator (paper §6): the discrete behaviour of one composite, as a ROS 2 node.

A pure event processor: it feeds the events of its composite's event topic (and its parent's
commands) into the life-cycle FSM of :mod:`.lifecycle` and publishes the events that FSM raises.
Common events are buffered and processed at the Coordinator's next update: after each tick of
its composite (:meth:`~itasc_core.composition.composer.Composer.coordinate`, when it holds events),
and between ticks by a timer at ``update_rate`` that runs only while there is something to update
(events held, a start-up state that may time out, a fault check under way): an idle timer woke
every composite's process 200 times a second for nothing. Priority events (``e_emergency``) are
processed on arrival (§6.2). It publishes its fully
qualified state on ``<composite namespace>/state`` on every change, and offers the operator
services of :mod:`.operator` (``~/raise_event``, ``~/recover``, ``~/stop``; ``~/compose`` when
its model has composition steps). A
parent's command of a composition step (``e_<c>_compose_<step>``) goes to the composite's
Composer, whose answer (``e_<c>_composed`` / ``e_<c>_compose_failed``) goes back up.
"""

from __future__ import annotations

import time
from typing import Iterable

from itasc_msgs.msg import CoordinatorState

from ..communication.event_names import (CHILD_ADDED, CHILD_REMOVED, COMPOSE_FAILED, COMPOSED, CONFIGURE, EMERGENCY,
                                          NOTIFICATIONS, RUN, START, STOP, TIMEOUT, event, from_parent,
                                          is_addressed_to, step_of)
from ..communication.qos import STATE_QOS
from ..entity import CompositeContext, Entity
from .lifecycle import LifecycleFsm, RunningFsmSpec
from .operator import Operator

__all__ = ['Coordinator', 'STARTUP_TIMEOUT']

#: How long a state on the way to Running (Configure, Start, PreRunning) may wait for the events
#: it needs before the composite goes to Safety (``e_<c>_timeout``): generous enough for a
#: composite process to come up on a loaded machine, short enough that a start that cannot
#: succeed ends in bounded time.
STARTUP_TIMEOUT = 10.0
#: A gap between two updates longer than this is time the process spent elsewhere (deploying or
#: configuring the entities of other composites in the same process): no time a state waited.
STALL = 0.1


class Coordinator(Entity):
    """Runs the life-cycle FSM of a composite on its events."""

    def __init__(
        self,
        *,
        composite: CompositeContext,
        children: Iterable[str] = (),
        running: RunningFsmSpec | None = None,
        safety_to_parent: Iterable[str] = (),
        steps: Iterable[str] = (),
        update_rate: float = 200.0,
        startup_timeout: float = STARTUP_TIMEOUT,
    ) -> None:
        super().__init__('coordinator', composite=composite)
        self.is_root = composite.parent_namespace is None
        self._to_parent = self._raiser if self.is_root else self.raiser(topic=composite.parent_events_topic)
        self._state_publisher = self.create_publisher(CoordinatorState, composite.state_topic, STATE_QOS)
        #: Every state entered, in order, with the event that caused it and when (time.monotonic).
        self.history: list[tuple[str, str, float]] = []
        self._entered_at = self._updated_at = time.monotonic()
        self._update_timer = self.create_timer(1.0 / update_rate, self.update)
        self.fsm = LifecycleFsm(
            composite=composite.name,
            children=children,
            is_root=self.is_root,
            raise_event=self._raise,
            on_state=self._publish_state,
            running=running,
            safety_to_parent=safety_to_parent,
        )
        self._safety_to_parent = tuple(safety_to_parent)
        self.operator = Operator(self, composite=composite, fsm=self.fsm, raise_own=self._raiser.raise_event,
                                 to_parent=None if self.is_root else self._to_parent, steps=steps,
                                 wake=self.wake)
        c = composite.name
        #: The answers of this composite's Composer to a composition step (:mod:`..composition.steps`).
        self._step_answers = (event(c, COMPOSED), event(c, COMPOSE_FAILED))
        self._structure = {event(c, CHILD_ADDED): self.fsm.adopt, event(c, CHILD_REMOVED): self.fsm.release}
        #: this composite's life-cycle commands: its parent's to give, on the parent's topic; on its
        #: own topic only a raw publish brings them, which would stop it behind its parent's back
        self._parents_commands = set() if self.is_root else {
            event(c, command) for command in (CONFIGURE, START, RUN, STOP, EMERGENCY)}
        self._events = self.listen(topics=[composite.events_topic], on_priority=self._process,
                                     accept=self._accepts, on_gap=self._gap, on_held=self.wake)
        self._parent_events = None if self.is_root else self.listen(
            topics=[composite.parent_events_topic], on_priority=self._process_parent,
            accept=self._accepts_parent, on_gap=self._gap, on_held=self.wake)
        self._notifications = {event(composite.name, n) for n in NOTIFICATIONS}
        self._startup_timeout = startup_timeout

    @property
    def state(self) -> str:
        return self.fsm.state

    def _accepts(self, name: str) -> bool:
        if name in self._parents_commands:
            self.get_logger().warning(f'{name} on {self.composite.events_topic} ignored: the life-cycle commands '
                                      f'of {self.composite.name} come from its parent')
            return False
        return self.fsm.is_relevant(name) or name in self._structure or name in self._step_answers \
            or self.operator.accepts(name)

    def _accepts_parent(self, name: str) -> bool:
        return is_addressed_to(self.composite.name, name)

    def _process_parent(self, msg) -> None:
        """Commands from the parent (:mod:`..communication.event_names`): those the life-cycle FSM
        reacts to go to the FSM (``e_<composite>_configure``, a configuration switch of the Running
        sub-FSM); any other ``e_<composite>_<x>`` is passed into this composite as ``e_<x>``."""
        if msg.source == self.get_fully_qualified_name():
            return  # our own notifications to the parent
        if self.operator.consume_parent(msg):
            return
        if step_of(self.composite.name, msg.name) is not None:  # a step of this composite: for its Composer
            self._raiser.raise_event(msg.name, detail=msg.detail)
            return
        if self.fsm.is_relevant(msg.name):
            self._process(msg)
        elif msg.name not in self._notifications:
            self._raiser.raise_event(from_parent(self.composite.name, msg.name), detail=msg.detail)

    def _gap(self, source: str, last: int, seq: int) -> None:
        self.get_logger().error(f'lost events from {source}: after #{last} came #{seq}')

    def wake(self) -> None:
        """Update soon (within an update period), and keep updating while there is something to
        update (:meth:`update` sends the timer back to sleep)."""
        if self._update_timer.is_canceled():
            self._updated_at = time.monotonic()  # asleep on purpose: not a stall (STALL)
            self._update_timer.reset()

    @property
    def holds_events(self) -> bool:
        """Whether common events wait for the next update."""
        return bool(len(self._events) or (self._parent_events is not None and len(self._parent_events)))

    def update(self) -> None:
        """Drain the event buffers: all common events that arrived since the last update."""
        for msg in self._events.drain():
            self._process(msg)
        if self._parent_events is not None:
            for msg in self._parent_events.drain():
                self._process_parent(msg)
        now = time.monotonic()
        if now - self._updated_at > STALL:
            self._entered_at += now - self._updated_at
        self._updated_at = now
        if self.fsm.starting_up and now - self._entered_at > self._startup_timeout:
            waiting = self.fsm.waiting_for()
            self._raiser.raise_event(event(self.composite.name, TIMEOUT), priority=True,
                                     detail=f'{self.state} waited {self._startup_timeout:g} s for {waiting}')
            self.fsm.process(event(self.composite.name, TIMEOUT))
        self.operator.update()
        if not (self.holds_events or self.fsm.starting_up or self.operator.checking):
            self._update_timer.cancel()

    def _process(self, msg) -> None:
        change = self._structure.get(msg.name)
        if change is not None:  # the Composer added or removed a child composite while running
            change(msg.detail)
            return
        if msg.name in self._step_answers:
            self.operator.composed(msg)
            if not self.is_root:  # the parent (its Composer, its recording) hears how it went
                self._to_parent.raise_event(msg.name, detail=msg.detail)
            if not self.fsm.is_relevant(msg.name):
                return
        if self.operator.consume(msg):
            return
        self.fsm.process(msg.name)
        self.operator.processed(msg)

    def _raise(self, name: str, to_parent: bool) -> None:
        raiser = self._to_parent if to_parent else self._raiser
        raiser.raise_event(name)  # the raiser marks priority events (event_names.is_priority)

    def _publish_state(self, state: str, previous: str, event: str) -> None:
        self.wake()  # a start-up state's timeout is checked at the updates
        self._entered_at = time.monotonic()
        self.history.append((state, event, self._entered_at))
        msg = CoordinatorState()
        msg.stamp = self.get_clock().now().to_msg()
        msg.composite = self.composite.name
        msg.state = state
        msg.previous_state = previous if previous != 'Init' else ''
        msg.event = event
        self._state_publisher.publish(msg)
        self.get_logger().debug(f'{state} <- {event}')
        self.operator.on_state(state, previous, self._safety_to_parent)

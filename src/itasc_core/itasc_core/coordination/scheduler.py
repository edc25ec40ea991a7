"""The Scheduler (paper §3.1, §6.1): the order of execution of a composite's Functional Entities.

Time-triggered by the parent's Scheduler (the root's by the Timer), it runs its computations in
the declared order and triggers child composites' Schedulers in the same tick, directly, never
through their Coordinators (§6.1: a Task must compute in the tick it is triggered). A child in
this process is called; a child in another process gets a trigger message on its trigger topic.
It answers the Coordinator's life-cycle events (initialise, activate, disengage, Safety) and
switches single entities on and off (``e_<entity>_activate`` / ``e_<entity>_deactivate``).

In Safety it keeps being triggered but computes nothing: every tick it has each entity bring its
outputs to their safe value (a Driver commands zero velocity at every tick, not once), and passes
the tick on to its children, which are in Safety too.
"""

from __future__ import annotations

import gc
import time
import traceback
from dataclasses import dataclass, field
from typing import Any, Callable

from itasc_msgs.msg import Trigger

from ..communication.event_names import (ACTIVATE, DEACTIVATE, DISENGAGE, DISENGAGED, SAFETY, SAFETY_EVENT,
                                          SCHEDULER_ACTIVATE, SCHEDULER_ACTIVATED, SCHEDULER_INITIALIZE,
                                          SCHEDULER_INITIALIZED, event, named)
from ..communication.cdr import received_as_sample, serialize
from ..communication.ports import LocalBus
from ..communication.qos import DATA_QOS, DATA_READER_QOS
from ..communication.trigger import TriggerSample, trigger_of
from ..computation.functional_entity import FunctionalEntity
from ..computation.monitor import Monitor
from ..entity import CompositeContext, Entity

__all__ = ['Scheduler']


@dataclass
class _Item:
    name: str
    run: Callable[[float], None]
    entity: FunctionalEntity | None = None
    enabled: bool = True
    #: A child composite in this process: its Scheduler, reached through its Composer.
    child: Any = None
    #: A child composite in another process: the publisher of its trigger topic, its namespace,
    #: and the topics of outputs in this process it reads, whose samples its trigger carries (each
    #: with the newest sample carried so far).
    trigger: Any = None
    namespace: str | None = None
    carried: dict[str, Any] = field(default_factory=dict)


class Scheduler(Entity):
    """Runs the composite's computations, in order, every tick it is given."""

    def __init__(self, *, composite: CompositeContext, remote_trigger: bool = False,
                 after_trigger: Callable[[], None] | None = None) -> None:
        super().__init__('scheduler', composite=composite)
        #: Called after each tick of the trigger topic (the Composer's coordination between ticks).
        self._after_trigger = after_trigger
        self._items: list[_Item] = []
        #: What a tick runs, in order: the items switched on (kept in step with them).
        self._runs: list[Callable[[float], None]] = []
        self._monitors: list[Monitor] = []
        self.active = False
        #: In Safety: each tick makes every entity safe instead of computing.
        self.safety = False
        self.ticks = 0
        #: The latest tick's time and when it came (``time.monotonic()``): the time now, in ticks' terms.
        self._tick_t, self._tick_at = 0.0, time.monotonic()
        self.faulted = False
        self._bus = LocalBus.of(self.context)
        c = composite.name
        self._handlers = {
            event(c, SCHEDULER_INITIALIZE): self._initialize,
            event(c, SCHEDULER_ACTIVATE): self._activate,
            event(c, DISENGAGE): self._disengage,
            event(c, SAFETY): self._safety,
        }
        self._events = self.listen(topics=[composite.events_topic], on_priority=self._on_event,
                                     accept=self._accepts, immediate=True)
        self._trigger_sub = None
        if remote_trigger:
            to_sample, raw = received_as_sample(Trigger)  # the CDR bytes, no ROS message built
            self._trigger_sub = self.create_subscription(
                Trigger, composite.trigger_topic, lambda received: self._on_trigger(to_sample(received)),
                DATA_READER_QOS, raw=raw)

    def _on_trigger(self, sample: TriggerSample) -> None:
        for topic, data in sample.carried():  # what the parent's entities wrote in this tick, first
            self._bus.deliver_carried(topic, data)
        self.tick(sample.t)
        if self._after_trigger is not None:
            self._after_trigger()

    # -- structure, set by the Composer ------------------------------------------------------------

    def add_entity(self, entity: FunctionalEntity, *, index: int | None = None, enabled: bool = True) -> None:
        self._insert(_Item(entity.entity_name, entity.update, entity, enabled), index)

    def add_child(self, name: str, child, *, enabled: bool = True) -> None:
        """A child composite in this process; ``child`` is its Composer (which has its Scheduler)."""
        self._insert(_Item(name, child.tick, enabled=enabled, child=child), None)

    def add_remote_child(self, name: str, namespace: str, *, enabled: bool = True) -> None:
        publisher = self.create_publisher(Trigger, f'{namespace}/trigger', DATA_QOS)
        carried: dict[str, Any] = {}
        lookup = self._bus.lookup

        def trigger(t: float) -> None:
            new = []
            for topic, sent in tuple(carried.items()):  # a re-composition may add a topic meanwhile
                output = lookup(topic)  # the output of the topic now (a swapped entity's is another)
                if output is not None and output.last is not None and output.last is not sent:
                    carried[topic] = output.last
                    new.append((topic, output.last))
            publisher.publish(serialize(trigger_of(t, new)))  # CDR bytes: no message built and converted
        self._insert(_Item(name, trigger, enabled=enabled, trigger=publisher, namespace=namespace, carried=carried),
                     None)

    def carry(self, name: str, topic: str) -> bool:
        """The trigger of child ``name`` (in another process) carries the samples the output of
        ``topic`` (in this process) writes, from now on (:mod:`..communication.trigger`); False if
        there is no such child."""
        for item in self._items:
            if item.name == name and item.trigger is not None:
                item.carried.setdefault(topic, None)
                return True
        return False

    def add_monitor(self, monitor: Monitor) -> None:
        self._monitors.append(monitor)

    def remove(self, name: str) -> None:
        for item in self._items:
            if item.name == name and item.trigger is not None:
                self.destroy_publisher(item.trigger)
            if item.name == name and item.namespace is not None:
                self._bus.set_idle(item.namespace, False)
        self._items = [i for i in self._items if i.name != name]
        self._runs = self._switched_on()
        self._monitors = [m for m in self._monitors if m.entity_name != name]

    def replace(self, entity: FunctionalEntity) -> None:
        """Run ``entity`` in place of the entity of its name, at its place in the order, switched
        on or off as that one was (a swap, :mod:`..composition.recompose`)."""
        for k, item in enumerate(self._items):
            if item.name == entity.entity_name:
                self._items[k] = _Item(item.name, entity.update, entity, item.enabled)
                self._runs = self._switched_on()
                return
        raise KeyError(entity.entity_name)

    def _insert(self, item: _Item, index: int | None) -> None:
        self.remove(item.name)
        self._items.insert(len(self._items) if index is None else index, item)
        self._enable(item, item.enabled)

    def _enable(self, item: _Item, enabled: bool) -> None:
        item.enabled = enabled
        self._runs = self._switched_on()
        if item.namespace is not None:  # a child composite in another process: off, it listens to nothing
            self._bus.set_idle(item.namespace, not enabled)

    def _switched_on(self) -> list[Callable[[float], None]]:
        return [item.run for item in self._items if item.enabled]

    @property
    def order(self) -> list[str]:
        return [i.name for i in self._items]

    # -- events -------------------------------------------------------------------------------------

    def _accepts(self, name: str) -> bool:
        return name in self._handlers or name.endswith((f'_{ACTIVATE}', f'_{DEACTIVATE}'))

    def _on_event(self, msg) -> None:
        handler = self._handlers.get(msg.name)
        if handler is not None:
            handler()
            return
        if msg.name in (named(ACTIVATE), named(DEACTIVATE)) and self._trigger_sub is not None:
            # This composite lives in its own process: its parent's e_<composite>_activate or
            # _deactivate reaches it through its Coordinator.
            if msg.name == named(ACTIVATE):
                self.activate_all()
            else:
                self.deactivate_all(self.now())
            return
        for item in self._items:
            if msg.name == event(item.name, ACTIVATE) and not item.enabled:
                self._enable(item, True)
                self._reactivate(item)
            elif msg.name == event(item.name, DEACTIVATE) and item.enabled:
                self._enable(item, False)
                self._deactivate(item, self.now())

    def _reactivate(self, item: _Item) -> None:
        if item.entity is not None:
            item.entity.activate()
        elif item.child is not None and item.child.scheduler is not None:
            item.child.scheduler.activate_all()

    def _deactivate(self, item: _Item, t: float) -> None:
        """``item`` was switched off at ``t`` (a child composite in another process hears it itself)."""
        if item.entity is not None:
            item.entity.deactivate(t)
        elif item.child is not None and item.child.scheduler is not None:
            item.child.scheduler.deactivate_all(t)

    def activate_all(self) -> None:
        """Everything this Scheduler runs was switched on again (its composite was)."""
        for item in self._items:
            self._reactivate(item)

    def deactivate_all(self, t: float) -> None:
        """Its composite was switched off at ``t``: everything this Scheduler runs that is on hears it."""
        for item in self._items:
            if item.enabled:
                self._deactivate(item, t)

    def now(self) -> float:
        """The time now, as the ticks count it (between two ticks: after the latest one)."""
        return self._tick_t + (time.monotonic() - self._tick_at)

    def _entities(self):
        return [i.entity for i in self._items if i.entity is not None] + self._monitors

    def _initialize(self) -> None:
        self.safety = False
        for entity in self._entities():
            entity.start()
        self.faulted = False
        self.raise_event(event(self.composite.name, SCHEDULER_INITIALIZED))

    def _activate(self) -> None:
        self.safety = False
        self.active = not self.faulted
        # What the bring-up built (~100k objects for an application) lives as long as the
        # composite: a full collection walking it paused the ticks ~60 ms (2-core VM); frozen, it is
        # left out, and a full collection walks only what was made since.
        gc.freeze()
        self.raise_event(event(self.composite.name, SCHEDULER_ACTIVATED))

    def _disengage(self) -> None:
        self.active = self.safety = False
        for entity in self._entities():
            entity.disengage()
        self.raise_event(event(self.composite.name, DISENGAGED))

    def _safety(self) -> None:
        self.active = False
        self.safety = True
        self._make_safe(0.0)

    def _make_safe(self, t: float) -> None:
        for item in self._items:
            try:
                if item.entity is not None:
                    item.entity.safe()
                else:
                    item.run(t)  # a child composite: its Scheduler is in Safety as well
            except Exception as err:  # noqa: BLE001 - one entity failing must not spare the others
                self.get_logger().error(f'{item.name} could not be made safe: {err}', throttle_duration_sec=1.0)

    # -- the time-triggered part --------------------------------------------------------------------

    def tick(self, t: float) -> None:
        if self.safety:
            self._make_safe(t)
            return
        if not self.active:
            return
        self.ticks += 1
        self._tick_t, self._tick_at = t, time.monotonic()
        try:
            for run in self._runs:
                run(t)
            for monitor in self._monitors:
                monitor.update(t)
        except Exception as err:  # noqa: BLE001 - any fault of a computation leads to Safety
            self.active = False
            self.faulted = True
            self.get_logger().error(f'computation failed, raising e_emergency: {err}\n{traceback.format_exc()}')
            self.raise_event(SAFETY_EVENT, priority=True, detail=f'{type(err).__name__}: {err}')

    def destroy_node(self) -> None:
        self._items.clear()
        self._runs.clear()
        self._monitors.clear()
        super().destroy_node()

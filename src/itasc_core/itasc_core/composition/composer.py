"""The Composer (paper §3.1, §6.1): creates and connects the entities of its composite, and
re-composes it at run time.

Coordinator–Composer pattern: the Composer holds composition steps with IDs and executes one when
the Coordinator raises the matching event, answering with a status event:

====================================  =============================================================
``e_<c>_deploy``                      create Scheduler, Functional Entities, Monitors, the entity
                                      of the outside events, (root) Timer, and every child
                                      composite's Coordinator, Configurator and Composer
                                      → ``e_<c>_deployed`` / ``e_<c>_deploy_failed``
``e_<c>_connect``                     check every connection's port metadata, connect the data
                                      flow → ``e_<c>_connected`` / ``e_<c>_connect_failed``
``e_<c>_cleanup_computation``         destroy Functional Entities incl. child composites
                                      → ``e_<c>_computation_cleaned``
``e_<c>_cleanup``                     destroy the other entities → ``e_<c>_cleaned``
``e_<c>_compose_<step>``              a composition step of the model while the composite runs:
                                      add, remove, swap entities, between two ticks
                                      (:mod:`.steps`) → ``e_<c>_composed`` /
                                      ``e_<c>_compose_failed`` (detail: ``<step>: <what, why>``)
``e_<c>_check_faults``                before a recovery from Safety: are the causes still there?
                                      Asks each entity named in the detail ``fault_persists()``,
                                      and counts a dead child process as one
                                      → ``e_<c>_faults_checked`` (:mod:`..coordination.recovery`)
====================================  =============================================================

A refused connection raises ``e_<c>_connection_refused`` naming both ports.
"""

from __future__ import annotations

import threading
import traceback
from typing import Callable

from ..communication.event_hub import EventHub
from ..communication.event_names import (BIND, CHECK_FAULTS, CLEANED, CLEANUP, CLEANUP_COMPUTATION,
                                          COMPUTATION_CLEANED, CONFIGURED, CONNECT, CONNECT_FAILED,
                                          CONNECTED, CONNECTION_REFUSED, DEPLOY, DEPLOY_FAILED, DEPLOYED,
                                          FAULTS_CHECKED, SAFETY_EVENT, STOP, STOPPED, event, owner_of)
from ..communication.events import EventListener, EventRaiser, events_topic
from ..communication.ports import LocalBus, SemanticMismatch, check_connection
from ..computation.functional_entity import FunctionalEntity
from ..computation.monitor import Monitor
from ..computation.outside_events import OutsideEvents
from ..configuration.configurator import Configurator
from ..coordination.coordinator import Coordinator
from ..coordination.lifecycle import RunningFsmSpec, RunningState, RunningTransition
from ..coordination.recovery import check_answer, parse_request
from ..coordination.scheduler import Scheduler
from ..coordination.timer import Timer
from ..entity import CompositeContext, Entity
from .deployment import Runtime, exit_reason
from .model import CompositeModel, ConnectionModel, EntityModel, MonitorModel
from .registry import resolve_kind
from .resolve import PortNotFound, port_of
from .steps import CompositionSteps

__all__ = ['Composer', 'assemble', 'bring_up', 'running_spec']


def running_spec(model: CompositeModel) -> RunningFsmSpec | None:
    """The Running sub-FSM of the model in the form the life-cycle FSM takes."""
    if model.running is None:
        return None
    return RunningFsmSpec(
        initial=model.running.initial,
        states=tuple(RunningState(name, tuple(s.raise_)) for name, s in model.running.states.items()),
        transitions=tuple(RunningTransition(t.source, t.target, tuple(t.when)) for t in model.running.transitions),
    )


def bring_up(*, model: CompositeModel, context: CompositeContext, runtime: Runtime,
             remote_trigger: bool = False) -> 'Composer':
    """Create a composite's Coordinator, Composer and Configurator (paper §6.1: what a bootstrap
    does for the root and a parent's Composer does for a child)."""
    composer = assemble(model=model, context=context, runtime=runtime, remote_trigger=remote_trigger)
    runtime.add(composer, composer.coordinator, composer.configurator)
    return composer


def assemble(*, model: CompositeModel, context: CompositeContext, runtime: Runtime,
             remote_trigger: bool = False) -> 'Composer':
    """:func:`bring_up` without handing the nodes to the executor (built off the tick path)."""
    composer = Composer(model=model, context=context, runtime=runtime, remote_trigger=remote_trigger)
    coordinator = Coordinator(
        composite=context,
        children=[child.name for child in model.children],
        running=running_spec(model),
        safety_to_parent=model.safety.raise_to_parent,
        steps=list(model.composition_steps),
    )
    configurator = Configurator(
        composite=context,
        configurations=model.configurations,
        initial=model.configure,
        entities=composer.functional_entities,
    )
    composer.coordinator, composer.configurator = coordinator, configurator
    return composer


class Composer(Entity):
    """Structure of one composite, for its whole life."""

    def __init__(self, *, model: CompositeModel, context: CompositeContext, runtime: Runtime,
                 remote_trigger: bool = False) -> None:
        super().__init__('composer', composite=context)
        self.model = model
        self.runtime = runtime
        self._remote_trigger = remote_trigger
        self.coordinator: Coordinator | None = None
        self.configurator: Configurator | None = None
        self.scheduler: Scheduler | None = None
        self.timer: Timer | None = None
        self.entities: dict[str, FunctionalEntity] = {}
        self.monitors: dict[str, Monitor] = {}
        self.outside_events: OutsideEvents | None = None
        self.children: dict[str, Composer | None] = {}  # None: hosted in another process
        #: Per child started in a process of its own: the endpoints on our event topic before it
        #: started, none of which can be its process's (see :meth:`when_children_listen`).
        self._endpoints_before: dict[str, set[bytes]] = {}
        self._pending: list[ConnectionModel] = []
        self._child_raisers: dict[str, EventRaiser] = {}
        #: Exported inputs the parent bound: port -> the topic that feeds it.
        self._bound: dict[str, str] = {}
        self._dead: set[str] = set()
        self._stopped: set[str] = set()  # children that reported stopped: their processes end by themselves
        self._stop_commanded: set[str] = set()
        self._ending: set[str] = set()  # children whose processes this Composer ends itself
        self._lock = threading.Lock()  # the process watchers run in threads of their own
        #: The composite's Functional Entities were cleaned up (it stopped): nothing more to compose.
        self.cleaned = False
        self._coordinated = -1  # EventListener.buffered when the last pass of :meth:`coordinate` began
        c = context.name
        self._steps = {
            event(c, DEPLOY): self.deploy,
            event(c, CONNECT): self.connect,
            event(c, CLEANUP_COMPUTATION): self.cleanup_computation,
            event(c, CLEANUP): self.cleanup,
        }
        self.composition = CompositionSteps(self)
        self._events = self.listen(topics=[context.events_topic], on_priority=self._on_event,
                                     accept=self._accepts, immediate=True)

    # -- events -------------------------------------------------------------------------------------

    def _child_event(self, name: str, what: str) -> str | None:
        """The child composite ``name`` = ``e_<child>_<what>`` is about, if it is one."""
        child = owner_of(name, what)
        return child if child in self.children else None

    def _accepts(self, name: str) -> bool:
        c = self.composite.name
        return name in self._steps or (bool(self._pending) and name.endswith(f'_{CONFIGURED}')) \
            or name == event(c, BIND) or name.endswith((f'_{STOPPED}', f'_{STOP}')) \
            or name == event(c, CHECK_FAULTS) or self.composition.accepts(name)

    def _on_event(self, msg) -> None:
        if self.composition.handle(msg):
            return
        if (child := self._child_event(msg.name, STOPPED)) is not None:
            self._stopped.add(child)
            self.composition.child_stopped(child)
            return
        if (child := self._child_event(msg.name, STOP)) is not None:
            with self._lock:
                self._stop_commanded.add(child)
                dead = child in self._dead
            if self.children[child] is None:  # in another process: what it writes stops coming now
                LocalBus.of(self.context).set_stopping(self.composite.child(child).namespace, True)
            if dead:
                self.raise_event(event(child, STOPPED), detail='its process had died')
            return
        if msg.name == event(self.composite.name, CHECK_FAULTS):
            number, sources = parse_request(msg.detail)
            self.raise_event(event(self.composite.name, FAULTS_CHECKED),
                             detail=check_answer(number, '; '.join(self.faults_still_there(sources))))
            return
        if msg.name == event(self.composite.name, BIND):
            port, _, topic = msg.detail.partition('|')
            topic, _, carried = topic.partition('|')
            if carried:  # the parent's process publishes it: the trigger carries its samples
                LocalBus.of(self.context).carry(topic)
            self.bind_export(port, topic)
            return
        step = self._steps.get(msg.name)
        if step is not None:
            step()
        elif self._pending:
            self.connect_pending(msg.name)

    def functional_entities(self) -> dict[str, FunctionalEntity]:
        """The entities and Monitors of this composite deployed now, by name (for the Configurator)."""
        return {**self.entities, **self.monitors}

    def faults_still_there(self, sources: list[str]) -> list[str]:
        """Why the faults the entities ``sources`` (node names) raised are still there: each is asked
        its ``fault_persists()`` (an entity that cannot tell says they are gone); and every child
        process that died (it cannot be reconfigured: a new start is needed)."""
        with self._lock:
            dead = sorted(self._dead)
        reasons = [f'the process of composite {name} is dead: only a new start brings it back' for name in dead]
        nodes = [*self.entities.values(), *self.monitors.values(), self.scheduler, self.configurator, self]
        by_name = {node.get_fully_qualified_name(): node for node in nodes if node is not None}
        for source in sources:
            check = getattr(by_name.get(source), 'fault_persists', None)
            reason = check() if check is not None else None
            if reason:
                reasons.append(f'{source.rsplit("/", 1)[-1]}: {reason}')
        return reasons

    def tick(self, t: float) -> None:
        """Trigger this composite's Scheduler (called by the parent's Scheduler, same process)."""
        if self.scheduler is not None:
            self.scheduler.tick(t)

    def coordinate(self) -> None:
        """After a tick of the whole hierarchy in this process (paper §6.2: the Timer's event
        triggers the Coordinators): the events the tick raised reach this process's listeners, and
        the Coordinators holding events take them, this composite's first, then its children's in
        this process, each command delivered before its receiver's turn. So a Monitor's event in
        one tick is acted on in the next: a configuration switch of the Running sub-FSM reaches the
        Task's Configurator between the two (issue #9: a reaction in two ticks, not a Coordinator
        update period per composite). A pass after which no listener of the process buffered an
        event finds nothing to take: it ends after the flush (the usual tick)."""
        hub = EventHub.of(self.context)
        if hub is not None:
            hub.flush()
        if EventListener.buffered == self._coordinated:
            return
        self._coordinated = EventListener.buffered  # what is buffered from now on is the next pass's
        self._coordinate(hub)

    def _coordinate(self, hub: EventHub | None) -> None:
        """:meth:`coordinate`, with the process's hub (the children here share it)."""
        if hub is not None:
            hub.flush()
        if self.coordinator is not None and self.coordinator.holds_events:
            self.coordinator.update()
            if hub is not None:
                hub.flush()
        for child in list(self.children.values()):
            if child is not None:
                child._coordinate(hub)

    # -- DeployEntities ---------------------------------------------------------------------------------

    def deploy(self) -> None:
        c = self.composite.name
        try:
            if self.scheduler is None:  # deploying again after Safety keeps what exists
                self.runtime.add(*self.build())
        except Exception as err:  # noqa: BLE001 - reported to the Coordinator, which goes to Safety
            self.get_logger().error(traceback.format_exc())
            self.raise_event(event(c, DEPLOY_FAILED), detail=f'{type(err).__name__}: {err}')
            return
        self._await_remote_children()

    def build(self) -> list:
        """Create the Scheduler, Functional Entities, Monitors, the entity of the outside events,
        (root) Timer and the child composites' Coordinators, Configurators and Composers; the nodes
        to hand to the executor (for a child composite added at run time: built off the tick path,
        :mod:`.steps`)."""
        nodes: list = []
        self.scheduler = Scheduler(composite=self.composite, remote_trigger=self._remote_trigger,
                                   after_trigger=self.coordinate)
        nodes.append(self.scheduler)
        for entity in self.model.entities:
            nodes += self._deploy_entity(entity)
        for monitor in self.model.monitors:
            nodes.append(self._deploy_monitor(monitor))
        if self.model.events:
            self.outside_events = OutsideEvents(composite=self.composite, events=self.model.events)
            nodes.append(self.outside_events)
        if self.composite.parent_namespace is None and self.model.rate:
            self.timer = Timer(composite=self.composite, scheduler=self.scheduler, rate=self.model.rate,
                               after_tick=self.coordinate)
            nodes.append(self.timer)
        return nodes

    def _await_remote_children(self) -> None:
        """Report deployed once every child process listens (see :meth:`when_children_listen`)."""
        c = self.composite.name
        self.when_children_listen(list(self.children), then=lambda: self.raise_event(event(c, DEPLOYED)),
                                  otherwise=lambda late: self.raise_event(
                                      event(c, DEPLOY_FAILED), detail=f'composite processes did not come up: {late}'))

    def when_children_listen(self, names: list[str], *, then: Callable[[], None],
                             otherwise: Callable[[list[str]], None], timeout: float = 30.0) -> None:
        """Call ``then`` once the process of every child of ``names`` that has one listens to our
        event topic and its Coordinator talks on it (both through that process's event hub), so that
        no command to it can be lost to DDS discovery; ``otherwise(late)`` after ``timeout`` s.
        Endpoints already there when the child's process was started are not that process's: a
        child composite added back soon after its removal would be seen listening through the
        endpoints of its old process, which lingers a moment after it stopped."""
        remote = {self.composite.child(name).namespace: self._endpoints_before.get(name, set())
                  for name in names if self.children.get(name, 0) is None}
        if not remote:
            then()
            return
        deadline = self.get_clock().now().nanoseconds + int(timeout * 1e9)
        topic = self.composite.events_topic

        def ready(infos, node: str, namespace: str) -> bool:
            return any(i.node_name == node and i.node_namespace == namespace
                       and bytes(i.endpoint_gid) not in remote[namespace] for i in infos)

        def poll() -> None:
            subscribers = self.get_subscriptions_info_by_topic(topic)
            publishers = self.get_publishers_info_by_topic(topic)
            if all(ready(subscribers, EventHub.NODE_NAME, ns) and ready(publishers, EventHub.NODE_NAME, ns)
                   for ns in remote):
                self.destroy_timer(timer)
                then()
            elif self.get_clock().now().nanoseconds > deadline:
                self.destroy_timer(timer)
                otherwise(list(remote))
        timer = self.create_timer(0.02, poll)

    def _deploy_entity(self, entity: EntityModel | CompositeModel) -> list:
        """Create one entity (a child composite: its Coordinator, Configurator and Composer, or its
        process) and schedule it; the nodes created."""
        scheduled = entity.name in self.model.schedule_order()
        enabled = entity.name not in self.model.inactive
        if isinstance(entity, CompositeModel):
            context = self.composite.child(entity.name)
            if self.runtime.separate(entity):  # per-composite, or on another host
                self.spawn_child(entity)
                if scheduled:
                    self.scheduler.add_remote_child(entity.name, context.namespace, enabled=enabled)
                return []
            child = assemble(model=entity, context=context, runtime=self.runtime)
            self.children[entity.name] = child
            if scheduled:
                self.scheduler.add_child(entity.name, child, enabled=enabled)
            return [child, child.coordinator, child.configurator]
        node = self.create_entity(entity)
        self.entities[entity.name] = node
        if scheduled:
            self.scheduler.add_entity(node, enabled=enabled)
        return [node]

    def create_entity(self, entity: EntityModel):
        """A leaf Functional Entity of this composite, not yet given to the executor."""
        return resolve_kind(entity.kind)(entity.name, composite=self.composite, parameters=entity.parameters)

    def spawn_child(self, entity: CompositeModel) -> None:
        """Start the process of child composite ``entity`` and watch it."""
        context = self.composite.child(entity.name)
        topic = self.composite.events_topic
        self._endpoints_before[entity.name] = {bytes(i.endpoint_gid) for i in (
            *self.get_subscriptions_info_by_topic(topic), *self.get_publishers_info_by_topic(topic))}
        self.runtime.spawn(model=entity, namespace=context.namespace, parent_namespace=self.composite.namespace)
        self.children[entity.name] = None
        LocalBus.of(self.context).set_stopping(context.namespace, False)
        process = self.runtime.process(context.namespace)
        threading.Thread(target=self._watch, args=(entity.name, process), daemon=True,
                         name=f'watch {entity.name}').start()

    def _deploy_monitor(self, monitor: MonitorModel):
        watched, _ = port_of(self.model, self.composite.namespace, monitor.watch)
        parameters = {
            'field': monitor.field, 'condition': monitor.condition, 'event': monitor.event, 'enabled': monitor.enabled,
            'enable_on': monitor.enable_on, 'disable_on': monitor.disable_on, **monitor.condition_parameters,
        }
        node = Monitor(monitor.name, composite=self.composite, parameters=parameters, watch=watched)
        self.monitors[monitor.name] = node
        self.scheduler.add_monitor(node)
        return node

    # -- ConnectEntities ----------------------------------------------------------------------------------

    def connect(self) -> None:
        c = self.composite.name
        refused = [problem for problem in map(self.connect_one, self.model.connections) if problem]
        for monitor in self.model.monitors:
            source, _ = port_of(self.model, self.composite.namespace, monitor.watch)
            self.monitors[monitor.name].watch.connect(source.id)
        if refused:
            self.raise_event(event(c, CONNECT_FAILED), detail='; '.join(refused))
        else:
            self.raise_event(event(c, CONNECTED))

    def connect_one(self, connection: ConnectionModel) -> str | None:
        """Connect one data flow; return why it was refused, or None."""
        ns = self.composite.namespace
        try:
            source, source_name = port_of(self.model, ns, connection.source)
            target, target_name = port_of(self.model, ns, connection.target)
            check_connection(source, target, source_name=source_name, target_name=target_name)
        except (SemanticMismatch, PortNotFound) as err:
            self.get_logger().error(str(err))
            self.raise_event(event(self.composite.name, CONNECTION_REFUSED), detail=str(err))
            return str(err)
        entity_name, _, port = connection.target.partition('.')
        if entity_name in self.entities:
            self.entities[entity_name].inputs[port].connect(source.id)
        else:
            self._bind_child(entity_name, port, source.id)
        return None

    def source_topic(self, ref: str, *, model: CompositeModel | None = None) -> str:
        """The topic of output ``ref`` (``entity.port``) of this composite (as ``model`` has it)."""
        return port_of(model or self.model, self.composite.namespace, ref)[0].id

    def _bind_child(self, child: str, port: str, topic: str) -> None:
        """Feed a port a child composite exports (the child's Composer connects its inside)."""
        composer = self.children.get(child)
        if composer is not None:
            composer.bind_export(port, topic)
        else:
            # The child lives in another process: ask its Composer on the child's event topic. If
            # this process publishes the topic, the child's trigger carries its samples.
            namespace = f'{self.composite.namespace}/{child}'
            raiser = self._child_raisers.get(namespace)
            if raiser is None:
                raiser = self._child_raisers[namespace] = self.raiser(topic=events_topic(namespace))
            carried = LocalBus.of(self.context).lookup(topic) is not None and self.scheduler.carry(child, topic)
            raiser.raise_event(event(child, BIND), detail=f'{port}|{topic}' + ('|carried' if carried else ''))

    def bind_export(self, port: str, topic: str) -> None:
        """Connect the inside of exported input ``port`` to ``topic``."""
        self._bound[port] = topic
        inner = self.model.exports[port]
        entity_name, _, inner_port = inner.partition('.')
        if entity_name in self.entities:
            self.entities[entity_name].inputs[inner_port].connect(topic)
        else:
            self._bind_child(entity_name, inner_port, topic)

    # -- run-time re-composition (:mod:`.steps`) ------------------------------------------------------

    def bound_inputs(self, entity: str) -> dict[str, str]:
        """Inputs of leaf ``entity`` fed through exports the parent bound: port -> topic."""
        return {inner.partition('.')[2]: self._bound[port] for port, inner in self.model.exports.items()
                if port in self._bound and inner.partition('.')[0] == entity}

    def retire_child(self, name: str) -> None:
        """A removed child composite stopped: its Coordinator, Configurator and Composer go (its
        process, if it has one, ends by itself)."""
        child = self.children.pop(name, None)
        namespace = self.composite.child(name).namespace
        raiser = self._child_raisers.pop(namespace, None)
        if raiser is not None:
            self.destroy_raiser(raiser)
        if child is not None:
            self.runtime.retire([child.coordinator, child.configurator, child])
            return
        with self._lock:
            self._ending.add(name)
        threading.Thread(target=self.runtime.join, args=(namespace,), daemon=True, name=f'join {name}').start()

    def connect_once_configured(self, connection: ConnectionModel) -> None:
        """Connect once the child composite at one of its ends reports configured (it was added)."""
        self._pending.append(connection)

    def connect_pending(self, name: str) -> None:
        ready = {child for child in self.children if name == event(child, CONFIGURED)}
        if not ready:
            return
        remaining = []
        for connection in self._pending:
            ends = {connection.source.split('.')[0], connection.target.split('.')[0]}
            if ends & ready:
                self.connect_one(connection)
            else:
                remaining.append(connection)
        self._pending = remaining

    def _watch(self, name: str, process) -> None:
        """Wait, in a thread of its own, for the process of child composite ``name`` to end: the
        kernel wakes it the moment the process dies, so the fault is known at once, whatever this
        process's executor is busy with. A death is a fault of this composite (Safety); when the
        Coordinator commands the dead child to stop, the Composer answers for it, so that this
        composite can still stop in order."""
        code = process.wait()
        with self._lock:
            if code == 0 or name in self._ending or name in self._dead:
                return  # it ended after it stopped, or because it was told to
            self._dead.add(name)
            stop_commanded = name in self._stop_commanded
        detail = f'process of composite {name} {exit_reason(process)}'
        self.raise_event(SAFETY_EVENT, priority=True, detail=detail)
        if stop_commanded:  # it died stopping: it will never answer
            self.raise_event(event(name, STOPPED), detail='its process had died')
        self.get_logger().error(detail)

    # -- Stopped ----------------------------------------------------------------------------------------

    def cleanup_computation(self) -> None:
        """Destroy the Functional Entities, child composites included (CleanupComputation)."""
        self.cleaned = True
        retired: list = list(self.entities.values())
        with self._lock:
            self._ending |= set(self.children)
        for name, child in self.children.items():
            if child is None:  # a child that never started (stopped during deploy) is ended at once
                self.runtime.join(f'{self.composite.namespace}/{name}', orderly=name in self._stopped)
            else:
                retired += [child.coordinator, child.configurator, child]
        self.entities.clear()
        self.children.clear()
        self.runtime.retire(retired)
        self.raise_event(event(self.composite.name, COMPUTATION_CLEANED))

    def cleanup(self) -> None:
        """Destroy the other entities of the composite (Cleanup)."""
        retired = [*self.monitors.values(), self.scheduler, self.timer, self.outside_events]
        self.monitors.clear()
        self.scheduler = self.timer = self.outside_events = None
        self.runtime.retire(node for node in retired if node is not None)
        self.raise_event(event(self.composite.name, CLEANED))

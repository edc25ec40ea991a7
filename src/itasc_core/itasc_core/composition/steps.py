"""Run-time re-composition, executed (paper §3.1: "the Coordinator can trigger a
(re-)composition"; §6.1: a Task added while the others keep running): the composition steps of
one Composer, each a transaction between two ticks.

``e_<c>_compose_<step>`` (raised by the Coordinator on entering a state of the Running sub-FSM, by
the operator's ``~/compose``, or by the parent's Composer for a step of its own) runs one step;
steps run one after another, in the order asked. A step:

1. is planned and checked against the composite as it is (:mod:`.recompose`), and its new
   Functional Entities (and added child composites, with their entities) are built and
   configured, in the process's worker thread, off the tick path: building a node takes
   milliseconds, more than a period of a fast loop;
2. runs the steps of child composites that belong to it (``e_<child>_compose_<step>``) and
   waits for their answers;
3. switches, in one callback of the executor's thread, hence between two ticks: swapped entities
   take over the topics, in-process links and latest samples of the ones they replace, at their
   place in the Scheduler's order; added ones are connected and scheduled; removed ones are
   unscheduled and disconnected. Everything new is started (Starting: a setpoint generator
   starts from where the Task is, a controller afresh), so the new structure computes at the
   next tick and the commanded velocity goes on from where it was.

It answers ``e_<c>_composed`` (detail ``<step>: <what changed>``) once the new structure computes,
or ``e_<c>_compose_failed`` (``<step>: <why>``) with nothing changed: the step did not fit, an
entity refused its parameters, a child's step failed, the composite stopped meanwhile. Removed
and replaced entities leave the ROS graph off the tick path (the Runtime destroys them in the
background); a removed child composite is stopped in order first, through its life-cycle
(``e_<c>_child_removed``: its parent's Coordinator commands the stop). An added child composite
goes through its life-cycle until Running (``e_<c>_child_added``: its parent's Coordinator
adopts it) before the step is answered; a fault of it on the way is a fault of the composite, as
at the first start.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from ..communication.event_names import (CHILD_ADDED, CHILD_REMOVED, COMPOSE_FAILED, COMPOSED, RUNNING,
                                          compose_step, event, step_of)
from ..communication.ports import LocalBus
from .model import CompositeModel, EntityModel
from .recompose import StepPlan, StepRefused, plan_step

if TYPE_CHECKING:
    from .composer import Composer

__all__ = ['CompositionSteps', 'CHILD_STEP_TIMEOUT']

#: How long a step waits for the answers of the child composites' steps that belong to it [s].
CHILD_STEP_TIMEOUT = 10.0


@dataclass
class _Built:
    """What a step built off the tick path, not yet in the executor."""

    leaves: dict[str, object] = field(default_factory=dict)
    #: Output ports of the new leaves, registered on the local bus at the switch.
    outputs: list = field(default_factory=list)
    #: Added child composites in this process: name -> their Composer (with their entities).
    children: dict[str, 'Composer'] = field(default_factory=dict)
    nodes: list = field(default_factory=list)


@dataclass
class _Step:
    name: str
    plan: StepPlan | None = None
    built: _Built | None = None
    #: Child composites whose step answer is awaited: name -> their step.
    waiting: dict[str, str] = field(default_factory=dict)
    failures: list[str] = field(default_factory=list)
    #: Added child composites not yet Running.
    adopting: set[str] = field(default_factory=set)
    timer: object | None = None


class CompositionSteps:
    """The composition steps of one Composer, run one at a time."""

    def __init__(self, composer: 'Composer') -> None:
        self._composer = composer
        self._queue: deque[str] = deque()
        self._current: _Step | None = None
        #: Removed child composites, stopping before their nodes go.
        self._removing: set[str] = set()

    # -- events -------------------------------------------------------------------------------------

    def accepts(self, name: str) -> bool:
        return step_of(self._composer.composite.name, name) is not None \
            or name.endswith((f'_{COMPOSED}', f'_{COMPOSE_FAILED}', f'_{RUNNING}'))

    def handle(self, msg) -> bool:
        """Handle an event of the composite's topic; whether it was a composition step's."""
        name = msg.name
        requested = step_of(self._composer.composite.name, name)
        if requested is not None:
            self._queue.append(requested)
            self._next()
            return True
        step = self._current
        if step is None:
            return False
        for child in list(step.waiting):
            if name in (event(child, COMPOSED), event(child, COMPOSE_FAILED)) \
                    and msg.detail.partition(':')[0] == step.waiting[child]:
                del step.waiting[child]
                if name == event(child, COMPOSE_FAILED):
                    step.failures.append(f'{child}: {msg.detail.partition(":")[2].strip()}')
                if not step.waiting:
                    self._children_answered()
                return True
        for child in list(step.adopting):
            if name == event(child, RUNNING):
                step.adopting.discard(child)
                if not step.adopting:
                    self._succeed()
                return False  # the Composer's other duties may need it too
        return False

    def child_stopped(self, child: str) -> None:
        """A child composite reported stopped: if it was removed, its nodes go now."""
        if child in self._removing:
            self._removing.discard(child)
            self._composer.retire_child(child)

    # -- one step after the other --------------------------------------------------------------------

    def _next(self) -> None:
        if self._current is not None or not self._queue:
            return
        composer = self._composer
        step = self._current = _Step(self._queue.popleft())
        model, namespace = composer.model, composer.composite.namespace
        future = composer.runtime.off_tick(lambda: self._prepare(step.name, model, namespace))
        future.add_done_callback(lambda done: composer.runtime.post(lambda: self._prepared(step, done)))

    def _prepare(self, name: str, model: CompositeModel, namespace: str) -> tuple[StepPlan, _Built]:
        """Off the tick path: plan, check, build and configure what the step adds."""
        plan = plan_step(model, namespace, name)
        built = _Built()
        try:
            with LocalBus.deferred() as outputs:
                for entity in [*plan.added, *(new for _, new in plan.swapped)]:
                    self._build(entity, built)
            built.outputs = outputs
        except Exception as err:  # noqa: BLE001 - an entity refused its parameters: nothing changes
            _destroy(built)
            raise StepRefused(f"'{entity.name}' cannot be created: {err}") from None
        return plan, built

    def _build(self, entity: EntityModel | CompositeModel, built: _Built) -> None:
        from .composer import assemble  # the Composer builds its children with these steps

        composer = self._composer
        if isinstance(entity, EntityModel):
            node = built.leaves[entity.name] = composer.create_entity(entity)
            built.nodes.append(node)
        elif not composer.runtime.separate(entity):
            child = assemble(model=entity, context=composer.composite.child(entity.name), runtime=composer.runtime)
            built.children[entity.name] = child
            built.nodes += [child, child.coordinator, child.configurator, *child.build()]

    def _prepared(self, step: _Step, done) -> None:
        """In the executor's thread: the step is built; run the children's steps, or switch."""
        try:
            step.plan, step.built = done.result()
        except StepRefused as err:
            self._fail(str(err))
            return
        except Exception as err:  # noqa: BLE001 - a bug must not leave the queue blocked
            self._fail(f'{type(err).__name__}: {err}')
            return
        if self._composer.cleaned:
            self._fail('the composite stopped meanwhile')
            return
        if not step.plan.children:
            self._switch()
            return
        step.waiting = dict(step.plan.children)
        for child, child_step in step.plan.children.items():
            if child not in self._composer.children:
                step.waiting.pop(child)
                step.failures.append(f"{child}: not deployed")
                continue
            self._composer.raise_event(compose_step(child, child_step),
                                       detail=f'{step.name} of {self._composer.composite.name}')
        if not step.waiting:
            self._children_answered()
            return
        step.timer = self._composer.create_timer(CHILD_STEP_TIMEOUT, self._children_timed_out)

    def _children_timed_out(self) -> None:
        step = self._current
        if step is None or not step.waiting:
            return
        step.failures += [f'{child}: no answer within {CHILD_STEP_TIMEOUT:g} s' for child in step.waiting]
        step.waiting.clear()
        self._children_answered()

    def _children_answered(self) -> None:
        step = self._current
        if step.timer is not None:
            self._composer.destroy_timer(step.timer)
            step.timer = None
        if step.failures:
            self._fail('; '.join(step.failures))
        elif self._composer.cleaned:
            self._fail('the composite stopped meanwhile')
        else:
            self._switch()

    # -- the switch, between two ticks ------------------------------------------------------------------

    def _switch(self) -> None:
        composer, step = self._composer, self._current
        plan, built = step.plan, step.built
        scheduler = composer.scheduler
        before = composer.model
        for entity in plan.removed:
            scheduler.remove(entity.name)
        for connection in plan.dropped:
            target, _, port = connection.target.partition('.')
            if target in composer.entities and target not in {e.name for e in plan.removed}:
                composer.entities[target].inputs[port].disconnect_from(composer.source_topic(connection.source,
                                                                                           model=before))
        retired = []
        for entity in plan.removed:
            if isinstance(entity, CompositeModel):
                self._removing.add(entity.name)
                composer.raise_event(event(composer.composite.name, CHILD_REMOVED), detail=entity.name)
            else:
                retired.append(composer.entities.pop(entity.name))
        composer.runtime.add(*built.nodes)
        composer.model = plan.model
        taken = set()
        for old_model, new_model in plan.swapped:
            old, new = composer.entities[old_model.name], built.leaves[new_model.name]
            for name, port in new.outputs.items():
                if name in old.outputs:
                    port.take_over(old.outputs[name])
                    taken.add(port)
            for name, port in new.inputs.items():
                if name in old.inputs:
                    port.take_over(old.inputs[name])
            composer.entities[new_model.name] = new
            scheduler.replace(new)
            retired.append(old)
        for port in built.outputs:
            if port not in taken:
                composer.runtime.bus.register(port)
        order = plan.model.schedule_order()
        for entity in plan.added:
            self._add(entity, built, index=order.index(entity.name) if entity.name in order else None)
        added_children = [e.name for e in plan.added if isinstance(e, CompositeModel)]
        for connection in plan.connections:
            if {connection.source.split('.')[0], connection.target.split('.')[0]} & set(added_children):
                composer.connect_once_configured(connection)
            else:
                composer.connect_one(connection)
        for name, node in built.leaves.items():
            for port, topic in composer.bound_inputs(name).items():
                node.inputs[port].connect(topic)
            node.start()
        for node in retired:
            for port in node.inputs.values():
                port.disconnect()
        composer.runtime.retire(retired)
        step.adopting = set(added_children)
        if not step.adopting:
            self._succeed()
            return
        # the parent's Coordinator adopts them once they listen (a process of its own takes a while)
        composer.when_children_listen(
            added_children,
            then=lambda: [composer.raise_event(event(composer.composite.name, CHILD_ADDED), detail=child)
                          for child in added_children],
            otherwise=lambda late: self._fail(f'composite processes did not come up: {late}'))

    def _add(self, entity: EntityModel | CompositeModel, built: _Built, *, index: int | None) -> None:
        composer = self._composer
        scheduled = index is not None
        if isinstance(entity, EntityModel):
            node = composer.entities[entity.name] = built.leaves[entity.name]
            if scheduled:
                composer.scheduler.add_entity(node, index=index)
        elif entity.name in built.children:
            child = composer.children[entity.name] = built.children[entity.name]
            if scheduled:
                composer.scheduler.add_child(entity.name, child)
        else:  # a process of its own: started now, adopted once it listens (see Composer._await_remote_children)
            composer.spawn_child(entity)
            if scheduled:
                composer.scheduler.add_remote_child(entity.name, composer.composite.child(entity.name).namespace)

    # -- answers ----------------------------------------------------------------------------------------

    def _succeed(self) -> None:
        step = self._current
        self._composer.get_logger().info(f'composition step {step.name}: {step.plan.summary()}')
        self._finish(COMPOSED, f'{step.name}: {step.plan.summary()}')

    def _fail(self, why: str) -> None:
        step = self._current
        if step.built is not None and not step.adopting:  # (an adopted child is the composite's now)
            built = step.built
            self._composer.runtime.off_tick(lambda: _destroy(built))
        self._composer.get_logger().error(f'composition step {step.name} refused: {why}')
        self._finish(COMPOSE_FAILED, f'{step.name}: {why}')

    def _finish(self, outcome: str, detail: str) -> None:
        self._current = None
        self._composer.raise_event(event(self._composer.composite.name, outcome), detail=detail)
        self._next()


def _destroy(built: _Built) -> None:
    """Undo a build: nothing of it was ever handed to the executor."""
    for node in reversed(built.nodes):
        node.destroy_node()
    built.nodes.clear()

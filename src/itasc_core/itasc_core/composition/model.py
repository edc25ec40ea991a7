"""The composition model: a tree of composites (paper §3, Fig. 1), validated with pydantic.

This is the generic model of the Composition Pattern that the runtime executes. An application
model in a domain language (the iTaSC DSL of ``itasc_bringup``) is transformed into it, and a
model of the pattern itself can be written in it directly (``config/apps/pattern_demo.yaml``).

A composite lists its Functional Entities (any of which may be a composite, to any depth), the
connections between their ports, the ports it exports to its parent, its named configurations
(Configurator), its monitors, its composition steps (Composer), its Running sub-FSM and what it
raises to its parent when it enters Safety (Coordinator), the topics and services of other ROS
nodes that raise its events (outside events), and the host it runs on (§4.4).
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from typing import Annotated, Any, Literal, Union

from pydantic import (ConfigDict, Discriminator, Field, Tag, ValidationError, field_validator, model_validator)

from ..computation.conditions import CONDITIONS
from ..computation.parameters import FileModel, TopicName, problems
from ..kinds import UnknownKind

__all__ = [
    'EntityModel',
    'CompositeModel',
    'ConnectionModel',
    'MonitorModel',
    'RunningModel',
    'RunningStateModel',
    'RunningTransitionModel',
    'CompositionStepModel',
    'SafetyModel',
    'OutsideEventModel',
    'OUTSIDE_EVENTS',
    'MIN_RATE',
    'MAX_RATE',
    'COMPOSITE_NODES',
    'switching_forever',
    'walk',
]

_NAME = r'^[A-Za-z][A-Za-z0-9_]{0,63}$'  # a ROS name token, 64 characters at most
#: The composite's own nodes (paper §6: its Coordinator, Composer, Configurator and Scheduler, the
#: root's Timer): no entity or Monitor of it may take one of their names.
COMPOSITE_NODES = ('coordinator', 'composer', 'configurator', 'scheduler', 'timer')
#: The rates a Timer can keep [Hz]: a tick every 100 s at the least, 100,000 ticks a second at most
#: (a rate beyond a float's period, or one that never ticks, is a typo, not a control rate).
MIN_RATE, MAX_RATE = 0.01, 100_000.0


class _Strict(FileModel):
    model_config = ConfigDict(frozen=True)


class EntityModel(_Strict):
    """A (leaf) Functional Entity: a kind from the registry and its ROS parameters."""

    name: str = Field(pattern=_NAME)
    kind: str = Field(min_length=1)
    parameters: dict[str, Any] = Field(default_factory=dict)


class ConnectionModel(_Strict):
    """Data flow from an output port to an input port, both written ``entity.port``."""

    source: str = Field(alias='from', pattern=r'^[A-Za-z][A-Za-z0-9_]*\.[A-Za-z][A-Za-z0-9_]*$')
    target: str = Field(alias='to', pattern=r'^[A-Za-z][A-Za-z0-9_]*\.[A-Za-z][A-Za-z0-9_]*$')


class MonitorModel(_Strict):
    """A Monitor (paper §4.1): a condition over a data-flow port that raises a named event. The
    condition is a registered kind (:mod:`..computation.conditions`); its parameters (``threshold``,
    ``band``, ``timeout``, ...) are further fields, checked by the kind's model."""

    model_config = ConfigDict(extra='allow', frozen=True)

    name: str = Field(pattern=_NAME)
    watch: str = Field(pattern=r'^[A-Za-z][A-Za-z0-9_]*\.[A-Za-z][A-Za-z0-9_]*$')
    field: str = ''
    condition: str = Field(min_length=1)
    event: str = Field(pattern=r'^e_[A-Za-z0-9_]+$')
    enabled: bool = True
    enable_on: list[str] = Field(default_factory=list)
    disable_on: list[str] = Field(default_factory=list)

    @model_validator(mode='after')
    def _condition(self) -> 'MonitorModel':
        try:
            CONDITIONS[self.condition].Parameters.model_validate(self.model_extra or {})
        except (ValidationError, UnknownKind) as err:
            raise ValueError(f"condition '{self.condition}': {problems(err)}") from None
        return self

    @property
    def condition_parameters(self) -> dict[str, Any]:
        """The parameters of its condition."""
        return dict(self.model_extra or {})


class RunningStateModel(_Strict):
    """A state of a Running sub-FSM and the events it raises on entry."""

    raise_: list[str] = Field(default_factory=list, alias='raise')
    """Events raised on entry."""


class RunningTransitionModel(_Strict):
    """A transition of a Running sub-FSM."""

    source: str = Field(alias='from')
    """The state it leaves."""
    target: str = Field(alias='to')
    """The state it enters."""
    when: list[str] = Field(min_length=1)
    """The events that trigger it (any of them)."""

    @field_validator('when', mode='before')
    @classmethod
    def _one_or_many(cls, value: Any) -> Any:
        return [value] if isinstance(value, str) else value


class RunningModel(_Strict):
    """The application-specific Running sub-FSM (paper §6.2): data, not code."""

    initial: str
    states: dict[str, RunningStateModel] = Field(min_length=1)
    transitions: list[RunningTransitionModel] = Field(default_factory=list)

    @model_validator(mode='after')
    def _known_states(self) -> 'RunningModel':
        if self.initial not in self.states:
            raise ValueError(f"initial state '{self.initial}' is not one of {sorted(self.states)}")
        for t in self.transitions:
            for end in (t.source, t.target):
                if end not in self.states:
                    raise ValueError(f"transition names unknown state '{end}'; known: {sorted(self.states)}")
        cycle = switching_forever({name: state.raise_ for name, state in self.states.items()},
                                  [(t.source, t.target, t.when) for t in self.transitions])
        if cycle:
            raise ValueError(f"states {' -> '.join(cycle)} would switch forever: each raises on entry an event "
                             'that leaves it for the next')
        return self


def switching_forever(raised: Mapping[str, Iterable[str]],
                      transitions: Iterable[tuple[str, str, Iterable[str]]]) -> list[str]:
    """A cycle of states of a Running sub-FSM (``raised``: the events each raises on entry;
    ``transitions``: from, to, when) each left at once by an event it raises on entry (a -> b on
    ``e_go``, b -> a on ``e_back``, a raising ``e_go``, b ``e_back``: the FSM switched at every
    pass, the console flooded and the rate halved), or [] when there is none."""
    at_once: dict[str, list[str]] = {}
    for source, target, when in transitions:
        if set(when) & set(raised.get(source, ())):
            at_once.setdefault(source, []).append(target)
    done: set[str] = set()

    def walk(state: str, path: list[str]) -> list[str]:
        if state in path:
            return path[path.index(state):] + [state]
        if state in done:
            return []
        for target in at_once.get(state, []):
            cycle = walk(target, path + [state])
            if cycle:
                return cycle
        done.add(state)
        return []
    return next((cycle for state in at_once if (cycle := walk(state, []))), [])


#: The name of the entity that raises a composite's outside events (reserved when it has some).
OUTSIDE_EVENTS = 'outside_events'


class OutsideEventModel(_Strict):
    """An event of the composite raised by another ROS node (a gripper, a PLC bridge): a message
    of ``type`` on ``topic`` (every message; with ``field`` and ``value``, each time the field turns
    equal to the value, e.g. a ``std_msgs/msg/Bool`` turning true), or a call of the service
    ``service`` of ``type`` the composite offers (e.g. ``std_srvs/srv/Trigger``; with ``field`` and
    ``value``, a call whose request field equals the value). Types and fields are checked against
    the installed interfaces before anything starts."""

    event: str = Field(pattern=r'^e_[A-Za-z0-9_]+$', description='The event raised in the composite.')
    topic: TopicName | None = Field(default=None, description=(
        'A topic another node publishes (absolute, or relative to the composite\'s namespace).'))
    service: TopicName | None = Field(default=None, description=(
        'A service the composite offers other nodes (a relative name lies in its namespace).'))
    type: str = Field(min_length=1, description=(
        'The message (topic) or service type: ``pkg/msg/Name``, ``pkg/srv/Name`` or ``pkg/Name``.'))
    field: str | None = Field(default=None, pattern=r'^[A-Za-z][A-Za-z0-9_]*(\.[A-Za-z][A-Za-z0-9_]*)*$',
                              description=('A field of the message (of the request), ``a.b`` for a '
                                           'nested one: the event is raised when it turns equal to value.'))
    value: bool | int | float | str | None = Field(default=None, description=(
        'The value of field that raises the event (a boolean, number or string).'))

    @model_validator(mode='after')
    def _complete(self) -> 'OutsideEventModel':
        if (self.topic is None) == (self.service is None):
            raise ValueError('give a topic or a service (one of them)')
        if (self.field is None) != (self.value is None):
            raise ValueError('field and value go together: the event is raised when the field equals the value')
        return self

    @property
    def kind(self) -> Literal['msg', 'srv']:
        """``msg`` for a topic, ``srv`` for a service."""
        return 'msg' if self.topic is not None else 'srv'


class SafetyModel(_Strict):
    """What a composite raises to its parent on entering Safety (the application decides)."""

    raise_to_parent: list[str] = Field(default_factory=list)


class CompositionStepModel(_Strict):
    """A composition step of the Composer with an ID (Coordinator–Composer pattern, §3.1): a
    change of the composite's structure while it runs (:mod:`.recompose`). Whether its ports agree
    depends on the structure when it runs (an earlier step may have changed it): the Composer checks
    then, and refuses a step that does not fit with ``e_<c>_compose_failed``."""

    add: list['EntityOrComposite'] = Field(default_factory=list, description=(
        'Entities and child composites to add.'))
    remove: list[str] = Field(default_factory=list, description=(
        'Entities and child composites to remove, with their connections.'))
    swap: list[EntityModel] = Field(default_factory=list, description=(
        'Entities that replace the entity of their name (a controller, a setpoint generator, the '
        'solver): the new one must have the ports the connections of the old one use, with the same '
        'metadata.'))
    connections: list[ConnectionModel] = Field(default_factory=list, description=(
        'Connections to make (between the entities of the composite after the step).'))
    children: dict[str, str] = Field(default_factory=dict, description=(
        'Steps of child composites that belong to this step: child name -> its step.'))

    @model_validator(mode='after')
    def _disjoint(self) -> 'CompositionStepModel':
        added, swapped = [e.name for e in self.add], [e.name for e in self.swap]
        for a, b, what in ((added, self.remove, 'added and removed'), (swapped, self.remove, 'swapped and removed'),
                           (added, swapped, 'added and swapped')):
            both = sorted(set(a) & set(b))
            if both:
                raise ValueError(f'{both} both {what} in one step')
        for names, what in ((added, 'added'), (self.remove, 'removed'), (swapped, 'swapped')):
            twice = sorted({n for n in names if names.count(n) > 1})
            if twice:
                raise ValueError(f'{twice} {what} twice')
        return self


class CompositeModel(_Strict):
    """A Composite Functional Entity (paper Fig. 1)."""

    name: str = Field(pattern=_NAME)
    entities: list['EntityOrComposite'] = Field(default_factory=list)
    schedule: list[str] | None = None
    #: Scheduled entities that start switched off (``e_<entity>_activate`` switches them on).
    inactive: list[str] = Field(default_factory=list)
    connections: list[ConnectionModel] = Field(default_factory=list)
    exports: dict[str, str] = Field(default_factory=dict)
    configurations: dict[str, dict[str, dict[str, Any]]] = Field(default_factory=dict)
    configure: list[str] = Field(default_factory=list)
    monitors: list[MonitorModel] = Field(default_factory=list)
    running: RunningModel | None = None
    safety: SafetyModel = Field(default_factory=SafetyModel)
    composition_steps: dict[str, CompositionStepModel] = Field(default_factory=dict)
    #: Topics and services of other ROS nodes that raise events of this composite.
    events: list[OutsideEventModel] = Field(default_factory=list)
    #: Root only: the rate of the Timer that triggers the root Scheduler.
    rate: float | None = Field(default=None, ge=MIN_RATE, le=MAX_RATE)
    #: The machine this composite runs on: the host agent of that name starts it (see
    #: ``itasc_core.composition.host_agent``). None: where its parent runs. Ignored on the root,
    #: which runs where the bootstrap runs.
    host: str | None = Field(default=None, pattern=_NAME)

    @model_validator(mode='after')
    def _consistent(self) -> 'CompositeModel':
        names = [e.name for e in self.entities] + [m.name for m in self.monitors]
        if self.events and OUTSIDE_EVENTS in names:
            raise ValueError(f"'{OUTSIDE_EVENTS}' is the name of the entity that raises the outside events: "
                             'choose another name')
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise ValueError(f'duplicate entity names {duplicates}')
        taken = sorted(set(names) & set(COMPOSITE_NODES))
        if taken:
            raise ValueError(f"'{taken[0]}' is the name of one of the composite's own nodes {COMPOSITE_NODES}: "
                             'choose another entity or monitor name')
        entity_names = {e.name for e in self.entities}
        for name in [*(self.schedule or []), *self.inactive]:
            if name not in entity_names:
                raise ValueError(f"schedule names unknown entity '{name}'; known: {sorted(entity_names)}")
        for c in self.connections:
            for end in (c.source, c.target):
                if end.split('.')[0] not in entity_names:
                    raise ValueError(f"connection end '{end}' names no entity of '{self.name}'")
        for config, targets in self.configurations.items():
            for target in targets:
                if target not in names:
                    raise ValueError(f"configuration '{config}' names unknown entity '{target}'")
        for config in self.configure:
            if config not in self.configurations:
                raise ValueError(f"configure names unknown configuration '{config}'; "
                                 f'known: {sorted(self.configurations)}')
        children = {c.name: c for c in self.children}
        for name, step in self.composition_steps.items():
            if not re.match(_NAME, name) or name == 'failed':  # e_<c>_compose_failed is the answer
                raise ValueError(f"composition step names must match {_NAME} and not be 'failed': {name!r}")
            for child, child_step in step.children.items():
                if child in children and child_step not in children[child].composition_steps:
                    raise ValueError(f"composition step '{name}': child '{child}' has no step '{child_step}'; "
                                     f'its steps: {sorted(children[child].composition_steps)}')
        return self

    @property
    def children(self) -> list['CompositeModel']:
        return [e for e in self.entities if isinstance(e, CompositeModel)]

    @property
    def leaves(self) -> list[EntityModel]:
        return [e for e in self.entities if isinstance(e, EntityModel)]

    def entity(self, name: str) -> 'EntityModel | CompositeModel':
        for e in self.entities:
            if e.name == name:
                return e
        raise KeyError(name)

    def schedule_order(self) -> list[str]:
        return list(self.schedule) if self.schedule is not None else [e.name for e in self.entities]


def _entity_kind(value: Any) -> str:
    if isinstance(value, dict):
        return 'composite' if 'entities' in value else 'entity'
    return 'composite' if isinstance(value, CompositeModel) else 'entity'


#: Entities are written ``{name, kind, parameters}`` or, for a composite, ``{name, entities, ...}``.
#: A composite is recognised by its ``entities``.
EntityOrComposite = Annotated[
    Union[Annotated[EntityModel, Tag('entity')], Annotated[CompositeModel, Tag('composite')]],
    Discriminator(_entity_kind),
]

CompositionStepModel.model_rebuild()
CompositeModel.model_rebuild()


def walk(root: CompositeModel, path: str = ''):
    """Yield ``(path, composite)`` for every composite of the tree, parents first."""
    here = f'{path}/{root.name}'
    yield here, root
    for child in root.children:
        yield from walk(child, here)

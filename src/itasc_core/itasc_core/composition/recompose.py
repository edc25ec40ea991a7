"""Run-time re-composition, planned (paper §3.1: the Composer is active for the composite's whole
life and responsible for run-time changes of its architecture). Plain Python, no ROS.

A composition step (:class:`~.model.CompositionStepModel`) adds, removes and swaps entities of a
running composite. :func:`plan_step` computes the structure after the step from the structure as
it is now, and checks it before anything is built, so that a step that cannot succeed changes
nothing (the Composer answers ``e_<c>_compose_failed`` with the reason):

* every name it removes or swaps is an entity of the composite, every name it adds is not;
* a removed entity is not exported to the parent (the parent's connections use it) and watched
  by no Monitor, and no remaining entity loses the only source of an input (an input that gathers
  several sources, as the Solver's rows, may lose one);
* a swapped entity is a leaf whose replacement has every port its connections and exports use,
  with the same metadata (message type, type, semantics): an exported or watched port keeps its
  metadata, so the parent's connections and the Monitors stay valid;
* every connection of the composite after the step joins ports that agree
  (:func:`~..communication.ports.check_connection`), every Monitor's watched port and every export
  exists.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..communication.ports import PortSpec, SemanticMismatch, check_connection
from .model import CompositeModel, ConnectionModel, EntityModel
from .registry import UnknownKind
from .resolve import PortNotFound, port_of

__all__ = ['StepPlan', 'StepRefused', 'plan_step']

Entity = EntityModel | CompositeModel


class StepRefused(ValueError):
    """A composition step that does not fit the composite as it is."""


@dataclass(frozen=True)
class StepPlan:
    """What one composition step changes."""

    step: str
    #: The composite after the step.
    model: CompositeModel
    added: list[Entity] = field(default_factory=list)
    #: As they were before the step.
    removed: list[Entity] = field(default_factory=list)
    #: ``(old, new)``.
    swapped: list[tuple[EntityModel, EntityModel]] = field(default_factory=list)
    #: Connections of the composite after the step with an end at an added or swapped entity.
    connections: list[ConnectionModel] = field(default_factory=list)
    #: Connections that end with the step (an end at a removed entity).
    dropped: list[ConnectionModel] = field(default_factory=list)
    #: Steps of child composites that belong to this one.
    children: dict[str, str] = field(default_factory=dict)

    def summary(self) -> str:
        parts = [f'{verb} {", ".join(names)}' for verb, names in (
            ('added', [e.name for e in self.added]), ('removed', [e.name for e in self.removed]),
            ('swapped', [new.name for _, new in self.swapped]),
            ('children', [f'{c}:{s}' for c, s in self.children.items()])) if names]
        return '; '.join(parts) or 'nothing to change'


def _ends(connection: ConnectionModel) -> set[str]:
    return {connection.source.split('.')[0], connection.target.split('.')[0]}


def plan_step(model: CompositeModel, namespace: str, step: str) -> StepPlan:
    """The plan of step ``step`` of ``model`` (the composite as it is now, living in
    ``namespace``); :class:`StepRefused` naming why it does not fit."""
    spec = model.composition_steps.get(step)
    if spec is None:
        raise StepRefused(f"'{model.name}' has no composition step '{step}'; "
                          f'steps: {sorted(model.composition_steps)}')
    names = {e.name: e for e in model.entities}
    for name in [*spec.remove, *(e.name for e in spec.swap)]:
        if name not in names:
            raise StepRefused(f"'{model.name}' has no entity '{name}' (entities: {sorted(names)})")
    for entity in spec.add:
        if entity.name in names:
            raise StepRefused(f"'{model.name}' already has an entity '{entity.name}'")
    swapped = [(names[new.name], new) for new in spec.swap]
    for old, _ in swapped:
        if isinstance(old, CompositeModel):
            raise StepRefused(f"'{old.name}' is a composite: only a Functional Entity can be swapped")
    removed = [names[name] for name in spec.remove]
    gone = set(spec.remove)
    _check_removal(model, gone)
    replacements = {new.name: new for _, new in swapped}
    entities = [replacements.get(e.name, e) for e in model.entities if e.name not in gone] + list(spec.add)
    kept = [c for c in model.connections if not _ends(c) & gone]
    dropped = [c for c in model.connections if _ends(c) & gone]
    schedule = None if model.schedule is None else [n for n in model.schedule if n not in gone] + \
        [e.name for e in spec.add]
    try:
        after = CompositeModel.model_validate({
            **model.model_dump(by_alias=True, exclude={'entities', 'connections', 'schedule', 'inactive'}),
            'entities': [e.model_dump(by_alias=True) for e in entities],
            'connections': [c.model_dump(by_alias=True) for c in [*kept, *spec.connections]],
            'schedule': schedule,
            'inactive': [n for n in model.inactive if n not in gone],
        })
    except ValueError as err:
        raise StepRefused(f'the composite after the step is not valid: {err}') from None
    for child in spec.children:
        if not any(c.name == child for c in after.children):
            raise StepRefused(f"step of child '{child}': '{model.name}' has no child composite '{child}' "
                              'after the step')
    _check_ports(model, after, namespace, swapped)
    changed = {e.name for e in spec.add} | set(replacements)
    return StepPlan(step=step, model=after, added=list(spec.add), removed=removed, swapped=swapped,
                    connections=[c for c in after.connections if _ends(c) & changed], dropped=dropped,
                    children=dict(spec.children))


def _check_removal(model: CompositeModel, gone: set[str]) -> None:
    for port, inner in model.exports.items():
        if inner.split('.')[0] in gone:
            raise StepRefused(f"'{inner.split('.')[0]}' cannot be removed: it is exported to the parent as '{port}'")
    for monitor in model.monitors:
        if monitor.watch.split('.')[0] in gone:
            raise StepRefused(f"'{monitor.watch.split('.')[0]}' cannot be removed: Monitor '{monitor.name}' "
                              'watches it')
    for connection in model.connections:
        source, target = connection.source.split('.')[0], connection.target.split('.')[0]
        if source in gone and target not in gone:
            entity = model.entity(target)
            if isinstance(entity, CompositeModel) or not _gathers(model, connection.target):
                raise StepRefused(f"'{source}' cannot be removed: {connection.target} would lose its source "
                                  f'{connection.source} (remove or swap it too)')


def _gathers(model: CompositeModel, ref: str) -> bool:
    """Whether leaf port ``ref`` gathers several sources (a Solver's rows)."""
    try:
        spec, _ = port_of(model, '', ref)
    except (PortNotFound, UnknownKind):
        return False
    return spec.multiple


def _same(a: PortSpec, b: PortSpec) -> bool:
    return (a.direction, a.msg_type, a.type, ''.join(a.semantics.split()), a.framework, a.multiple) == \
        (b.direction, b.msg_type, b.type, ''.join(b.semantics.split()), b.framework, b.multiple)


def _check_ports(before: CompositeModel, after: CompositeModel, namespace: str,
                 swapped: list[tuple[EntityModel, EntityModel]]) -> None:
    def port(model: CompositeModel, ref: str) -> tuple[PortSpec, str]:
        try:
            return port_of(model, namespace, ref)
        except (PortNotFound, UnknownKind) as err:
            raise StepRefused(f"'{ref}': {err}") from None

    for connection in after.connections:
        source, source_name = port(after, connection.source)
        target, target_name = port(after, connection.target)
        try:
            check_connection(source, target, source_name=source_name, target_name=target_name)
        except SemanticMismatch as err:
            raise StepRefused(str(err)) from None
    swapped_names = {new.name for _, new in swapped}
    for monitor in after.monitors:
        new, where = port(after, monitor.watch)
        if monitor.watch.split('.')[0] in swapped_names and not _same(port(before, monitor.watch)[0], new):
            raise StepRefused(f"{where}: Monitor '{monitor.name}' watches it, its metadata would change")
    for name, inner in after.exports.items():
        new, where = port(after, inner)
        if inner.split('.')[0] in swapped_names and not _same(port(before, inner)[0], new):
            raise StepRefused(f"{where}: exported as '{name}', its metadata would change "
                              f'({new.msg_type_name} {new.type!r} {new.semantics!r})')

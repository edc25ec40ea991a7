"""Checks of a composition model before anything starts (paper §3.3, §4.3): what the Composers
would otherwise find only at run time, each a :class:`ModelError` naming the file, the path inside
it and the value.

Every leaf entity's kind is registered and takes the parameters it is given (its parameter model,
:mod:`..computation.parameters`, validates them); every exported port, connection end and watched
port exists (port metadata from the model alone, :mod:`.resolve`), and every connection joins ports
that agree on their metadata. Composition steps add and swap entities that pass the same checks, and
remove and swap entities the composite has or a step adds; whether a step's ports fit depends on
the structure when it runs (an earlier step may have changed it), so the Composer checks that then
(:mod:`.recompose`). Every outside event names an installed message or service type, and a field it has
(:func:`check_outside_event`, also used by the iTaSC application model's checks).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pydantic import ValidationError

from ..communication.interfaces import InterfaceError, check_value, field_type, interface
from ..communication.ports import SemanticMismatch, check_connection
from .loader import ModelError, format_loc, source_of
from .model import CompositeModel, EntityModel, OutsideEventModel
from .registry import UnknownKind, resolve_kind
from .resolve import PortNotFound, port_of

__all__ = ['check_composite', 'check_outside_event']

Loc = tuple[Any, ...]


def check_composite(model: CompositeModel, sources: dict[Loc, Path], *, at: Loc = ('composite',)) -> None:
    """Raise the first :class:`ModelError` of ``model`` (found at ``at`` in the loaded tree)."""
    _composite(model, sources, at, namespace=f'/{model.name}')


def _error(sources: dict[Loc, Path], loc: Loc, message: str) -> ModelError:
    path, inner = source_of(loc, sources)
    return ModelError(str(path), format_loc(inner), message)


def _composite(model: CompositeModel, sources: dict[Loc, Path], loc: Loc, *, namespace: str) -> None:
    for i, entity in enumerate(model.entities):
        if isinstance(entity, CompositeModel):
            _composite(entity, sources, loc + ('entities', i), namespace=f'{namespace}/{entity.name}')
        else:
            _entity(entity, sources, loc + ('entities', i))
    for name, step in model.composition_steps.items():
        at = loc + ('composition_steps', name)
        for j, entity in enumerate(step.add):
            if isinstance(entity, EntityModel):
                _entity(entity, sources, at + ('add', j))
            else:
                _composite(entity, sources, at + ('add', j), namespace=f'{namespace}/{entity.name}')
        for j, entity in enumerate(step.swap):
            _entity(entity, sources, at + ('swap', j))
        known = {e.name for e in model.entities} | {e.name for s in model.composition_steps.values() for e in s.add}
        for key, names in (('remove', step.remove), ('swap', [e.name for e in step.swap])):
            for j, entity_name in enumerate(names):
                if entity_name not in known:
                    raise _error(sources, at + (key, j) + (('name',) if key == 'swap' else ()),
                                 f"'{model.name}' has no entity '{entity_name}', and no step adds one; "
                                 f'entities: {sorted(known)}')

    def port(ref: str, at: Loc):
        try:
            return port_of(model, namespace, ref)
        except (PortNotFound, UnknownKind) as err:
            raise _error(sources, at, f"'{ref}': {err}") from None

    for name, ref in model.exports.items():
        port(ref, loc + ('exports', name))
    for k, connection in enumerate(model.connections):
        source, source_name = port(connection.source, loc + ('connections', k, 'from'))
        target, target_name = port(connection.target, loc + ('connections', k, 'to'))
        try:
            check_connection(source, target, source_name=source_name, target_name=target_name)
        except SemanticMismatch as err:
            raise _error(sources, loc + ('connections', k), str(err)) from None
    for k, monitor in enumerate(model.monitors):
        port(monitor.watch, loc + ('monitors', k, 'watch'))
    for k, outside in enumerate(model.events):
        problem = check_outside_event(outside)
        if problem is not None:
            raise _error(sources, loc + ('events', k, problem[0]), problem[1])


def check_outside_event(spec: OutsideEventModel) -> tuple[str, str] | None:
    """Whether an outside event names an installed interface type and a field it has, with a
    value that field can take: None, or the key at fault (``type``, ``field``, ``value``) and why."""
    try:
        cls = interface(spec.type, spec.kind)
    except InterfaceError as err:
        return 'type', str(err)
    if spec.field is None:
        return None
    try:
        request = cls.Request if spec.kind == 'srv' else cls  # type: ignore[attr-defined]  # generated by rosidl
        ros_type = field_type(request, spec.field)
    except InterfaceError as err:
        return 'field', f"'{spec.field}': {err}"
    try:
        check_value(ros_type, spec.value)
    except InterfaceError as err:
        return 'value', f"field '{spec.field}': {err}"
    return None


def _entity(entity: EntityModel, sources: dict[Loc, Path], loc: Loc) -> None:
    try:
        cls = resolve_kind(entity.kind)
    except UnknownKind as err:
        raise _error(sources, loc + ('kind',), str(err)) from None
    try:
        params = cls.parameters_of(entity.parameters)
    except ValidationError as err:
        first = err.errors()[0]
        raise _error(sources, loc + ('parameters', *first['loc']), f"{entity.kind}: {first['msg']}") from None
    try:
        cls.port_specs(params)
    except (TypeError, ValueError, KeyError, IndexError) as err:
        raise _error(sources, loc + ('parameters',), f'{entity.kind} cannot declare its ports: {err}') from None

"""Port metadata from the model alone (paper §4.3, §7.3): which port an ``entity.port`` reference
of a composite names, down through the ports a child composite exports, with its topic.

Because a Functional Entity declares its ports as a function of its parameters, any Composer can
check a connection without the entities being instantiated, in whatever process they live.
"""

from __future__ import annotations

import weakref

from ..communication.ports import PortSpec
from ..computation.functional_entity import FunctionalEntity
from .model import CompositeModel, EntityModel
from .registry import resolve_kind

__all__ = ['port_of', 'PortNotFound']


class PortNotFound(LookupError):
    pass


def port_of(model: CompositeModel, namespace: str, ref: str) -> tuple[PortSpec, str]:
    """The metadata (with topic) of port ``ref`` = ``entity.port`` of composite ``model`` living in
    ``namespace``, and the fully qualified name of the leaf port it resolves to."""
    entity_name, _, port_name = ref.partition('.')
    try:
        entity = model.entity(entity_name)
    except KeyError:
        raise PortNotFound(f"'{model.name}' has no entity '{entity_name}'") from None
    if isinstance(entity, CompositeModel):
        inner = entity.exports.get(port_name)
        if inner is None:
            raise PortNotFound(f"composite '{entity.name}' exports no port '{port_name}' "
                               f'(exports: {sorted(entity.exports)})')
        return port_of(entity, f'{namespace}/{entity.name}', inner)
    return _leaf_port(entity, namespace, port_name)


#: The ports of every entity model resolved so far, by the model object's id (models are not
#: changed once made; an entry goes with its model). An entity that many connect to, a Scene or a
#: Solver whose parameters grow with the Tasks, had its parameters validated once per connection:
#: the bring-up of a program grew with the square of its Tasks.
_specs: dict[int, tuple[weakref.ref, list[PortSpec]]] = {}


def _port_specs(entity: EntityModel) -> list[PortSpec]:
    known = _specs.get(id(entity))
    if known is not None and known[0]() is entity:
        return known[1]
    cls = resolve_kind(entity.kind)
    specs = cls.port_specs(cls.parameters_of(entity.parameters))
    key = id(entity)
    _specs[key] = (weakref.ref(entity, lambda _: _specs.pop(key, None)), specs)
    return specs


def _leaf_port(entity: EntityModel, namespace: str, port_name: str) -> tuple[PortSpec, str]:
    specs = _port_specs(entity)
    for spec in specs:
        if spec.name == port_name:
            topic = FunctionalEntity.port_topic(namespace, entity.name, port_name)
            return spec.with_id(topic), f'{namespace}/{entity.name}.{port_name}'
    raise PortNotFound(f"entity '{entity.name}' ({entity.kind}) has no port '{port_name}' "
                       f'(ports: {[s.name for s in specs]})')

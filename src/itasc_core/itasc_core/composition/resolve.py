"""Port metadata from the model alone (paper §4.3, §7.3): which port an ``entity.port`` reference
of a composite names, down through the ports a child composite exports, with its topic.

Because a Functional Entity declares its ports as a function of its parameters, any Composer can
check a connection without the entities being instantiated, in whatever process they live.
"""

from __future__ import annotations

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


def _leaf_port(entity: EntityModel, namespace: str, port_name: str) -> tuple[PortSpec, str]:
    cls = resolve_kind(entity.kind)
    params = cls.parameters_of(entity.parameters)
    for spec in cls.port_specs(params):
        if spec.name == port_name:
            topic = FunctionalEntity.port_topic(namespace, entity.name, port_name)
            return spec.with_id(topic), f'{namespace}/{entity.name}.{port_name}'
    names = [s.name for s in cls.port_specs(params)]
    raise PortNotFound(f"entity '{entity.name}' ({entity.kind}) has no port '{port_name}' (ports: {names})")

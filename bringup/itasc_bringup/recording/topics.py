"""The data-flow topics of a composition model (paper §4.3, §7.3): every output port of every
Functional Entity of the tree, with its topic and message type, known from the model alone
(each entity kind declares its ports as a function of its parameters), so a recorder can
subscribe to them before the hierarchy is configured and miss none of the first tick.
"""

from __future__ import annotations

from itasc_core.composition.model import CompositeModel, EntityModel
from itasc_core.composition.registry import resolve_kind
from itasc_core.computation.functional_entity import FunctionalEntity

__all__ = ['data_flow_topics']


def data_flow_topics(model: CompositeModel, *, namespace: str | None = None) -> dict[str, str]:
    """``topic -> pkg/msg/Type`` of every output port in ``model`` living in ``namespace``
    (default ``/<model name>``), entities added by composition steps included."""
    namespace = namespace if namespace is not None else f'/{model.name}'
    topics: dict[str, str] = {}
    entities = list(model.entities) + [e for step in model.composition_steps.values() for e in step.add]
    for entity in entities:
        if isinstance(entity, CompositeModel):
            topics.update(data_flow_topics(entity, namespace=f'{namespace}/{entity.name}'))
        else:
            topics.update(_outputs(entity, namespace))
    return topics


def _outputs(entity: EntityModel, namespace: str) -> dict[str, str]:
    cls = resolve_kind(entity.kind)
    params = cls.parameters_of(entity.parameters)
    return {FunctionalEntity.port_topic(namespace, entity.name, spec.name): spec.msg_type_name
            for spec in cls.port_specs(params) if spec.direction == 'output'}

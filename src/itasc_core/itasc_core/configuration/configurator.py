"""The Configurator (paper §5): holds named configurations and applies one when the Coordinator
raises the event with its name (Coordinator–Configurator pattern), answering with a status event.

A configuration is a set of ROS 2 parameter values per entity of this composite, e.g.
``high_accuracy_control: {CC: {kp: 8.0}}`` applied on ``e_high_accuracy_control`` and answered by
``e_high_accuracy_control_applied`` (or ``..._failed``). On ``e_<composite>_configure_entities``
it applies the composite's initial configurations and answers ``e_<composite>_entities_configured``.
The Configurator itself is configured by whoever creates it (the parent's Composer, or the
bootstrap for the root, §5.1): it is handed its configurations at construction.

It also serves the parameters of its composite's entities to ``ros2 param``, as
``<entity>.<parameter>`` on its own node, and announces every change of them on
``/parameter_events`` as its own (:mod:`.parameter_service`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Callable

from ..communication.event_names import (APPLIED, CONFIGURE_ENTITIES, CONFIGURE_FAILED, ENTITIES_CONFIGURED,
                                          FAILED, event, named)
from ..computation.functional_entity import FunctionalEntity
from ..entity import CompositeContext, Entity
from .parameter_service import EntityParameters

__all__ = ['Configurator']

Configuration = dict[str, dict[str, Any]]


class Configurator(Entity):
    """Applies named configurations to the entities of its composite."""

    def __init__(
        self,
        *,
        composite: CompositeContext,
        configurations: dict[str, Configuration],
        initial: list[str],
        entities: Callable[[], Mapping[str, FunctionalEntity]],
    ) -> None:
        super().__init__('configurator', composite=composite)
        self.configurations = dict(configurations)
        self.initial = list(initial)
        self._entities = entities
        self.parameters = EntityParameters(self, entities=entities)
        self.applied: list[str] = []
        #: The event of each configuration (``e_<configuration>``).
        self._events_of = {named(c): c for c in self.configurations}
        self._events = self.listen(topics=[composite.events_topic], on_priority=self._on_event,
                                     accept=self._accepts, immediate=True)

    def _accepts(self, name: str) -> bool:
        return name == self._configure_event or name in self._events_of

    @property
    def _configure_event(self) -> str:
        return event(self.composite.name, CONFIGURE_ENTITIES)

    def _on_event(self, msg) -> None:
        c = self.composite.name
        if msg.name == self._configure_event:
            failure = next(filter(None, (self.apply(name) for name in self.initial)), None)
            if failure:
                self.raise_event(event(c, CONFIGURE_FAILED), detail=failure)
            else:
                self.raise_event(event(c, ENTITIES_CONFIGURED))
            return
        name = self._events_of[msg.name]
        failure = self.apply(name)
        self.raise_event(event(name, FAILED if failure else APPLIED), detail=failure or '')

    def apply(self, name: str) -> str | None:
        """Apply configuration ``name``; return why it failed, or None."""
        for entity_name, values in self.configurations[name].items():
            entity = self._entities().get(entity_name)
            if entity is None:
                return f"configuration '{name}': entity '{entity_name}' is not deployed"
            try:
                parameters = entity.ros_parameters(values)
            except ValueError as err:
                return f"configuration '{name}' on {entity_name}: {err}"
            with entity.set_by(f'configuration {name}'):
                results = entity.set_parameters(parameters)
            self.parameters.announce(entity_name, [p for p, r in zip(parameters, results) if r.successful])
            for result in results:
                if not result.successful:
                    return f"configuration '{name}' on {entity_name}: {result.reason}"
        self.applied.append(name)
        self.get_logger().debug(f'applied configuration {name}')
        return None

"""From ``ros2 param dump`` of running composites to a named configuration of the application model
(paper §5; issue #14 item 4): gains tuned on a running application with ``ros2 param set`` go back
into its model file.

A composite's entities' parameters are its Configurator's (``<composite>/configurator``, named
``<entity>.<parameter>``: :mod:`itasc_core.configuration.parameter_service`), so a dump holds, per
Configurator, ``ros__parameters`` with one entry per entity (nested, as ``ros2 param dump`` writes
dotted names, or dotted). A Task's Constraint Controller (``CC``) gives the Task's ``controller``
settings, its Rows (``Rows``) its ``weights`` and ``priority``, a Monitor its ``threshold``: what a
named configuration of the model sets (:class:`~.schema.Settings`), checked by the same schema;
the composite's other entities are left out. Values that are not finite (``max_output: .inf``, no
saturation) are left out too: a model file holds finite numbers.
"""

from __future__ import annotations

import math
from typing import Any

from itasc_core.computation.parameters import nest
from itasc_tasks.controllers import CONTROLLERS

from .schema import Settings

__all__ = ['configuration_of']

ROS_PARAMETERS = 'ros__parameters'
CONFIGURATOR = 'configurator'


def _finite(value: Any) -> bool:
    return not (isinstance(value, float) and not math.isfinite(value))


def _settings(task: str, entity: str, parameters: dict[str, Any]) -> tuple[str, dict[str, Any]] | None:
    """What a named configuration sets of ``entity`` of composite ``task``, as (target, settings);
    None if nothing."""
    if entity == 'CC' and parameters.get('kind') in CONTROLLERS:
        controller = {k: parameters[k] for k in CONTROLLERS[parameters['kind']].Parameters.model_fields
                      if k in parameters and _finite(parameters[k])}
        return task, {'controller': controller}
    if entity == 'Rows' and {'weights', 'priority'} <= set(parameters):
        return task, {'weights': list(parameters['weights']), 'priority': parameters['priority']}
    if {'threshold', 'condition'} <= set(parameters):
        return entity, {'threshold': parameters['threshold']}
    return None


def configuration_of(dump: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """The named configuration (target -> settings) that sets what ``dump`` (``ros2 param dump`` of
    Configurators: node -> ``ros__parameters``) holds; ValueError naming the node it cannot use."""
    if not isinstance(dump, dict) or not dump:
        raise ValueError('expected the output of ros2 param dump: node name -> ros__parameters')
    configuration: dict[str, dict[str, Any]] = {}
    for node, content in dump.items():
        if not isinstance(content, dict) or not isinstance(content.get(ROS_PARAMETERS), dict):
            raise ValueError(f'{node}: expected {ROS_PARAMETERS}')
        *_, task, configurator = ['', *str(node).strip('/').split('/')]
        if configurator != CONFIGURATOR:
            raise ValueError(f"{node}: expected the dump of a composite's {CONFIGURATOR} "
                             '(<composite>/configurator: its entities\' parameters, as <entity>.<parameter>)')
        found = [_settings(task, entity, parameters) for entity, parameters in nest(content[ROS_PARAMETERS]).items()
                 if isinstance(parameters, dict)]
        if not any(found):
            raise ValueError(f"{node}: a named configuration sets a Task's controller (its CC), weights and priority "
                             "(its Rows) or a Monitor's threshold; this composite has none of them")
        for target, settings in filter(None, found):
            merged = {**configuration.get(target, {}), **settings}
            Settings.model_validate(merged)  # what the model file would take
            configuration[target] = merged
    return configuration

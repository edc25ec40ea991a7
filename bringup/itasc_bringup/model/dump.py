"""From ``ros2 param dump`` of running entities to a named configuration of the application model
(paper §5; issue #14 item 4): gains tuned on a running application with ``ros2 param set`` go back
into its model file.

A dump holds, per node, ``ros__parameters``. A Task's Constraint Controller (``<program>/<Task>/CC``)
gives the Task's ``controller`` settings, its Rows (``<program>/<Task>/Rows``) its ``weights`` and
``priority``, a Monitor (``<program>/<monitor>``) its ``threshold``: what a named configuration of
the model sets (:class:`~.schema.Settings`), checked by the same schema. Values that are not
finite (``max_output: .inf``, no saturation) are left out: a model file holds finite numbers.
"""

from __future__ import annotations

import math
from typing import Any

from itasc_tasks.controllers import CONTROLLERS

from .schema import Settings

__all__ = ['configuration_of']

ROS_PARAMETERS = 'ros__parameters'


def _finite(value: Any) -> bool:
    return not (isinstance(value, float) and not math.isfinite(value))


def _settings(node: str, parameters: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    path = node.strip('/').split('/')
    if path[-1] == 'CC' and parameters.get('kind') in CONTROLLERS:
        controller = {k: parameters[k] for k in CONTROLLERS[parameters['kind']].Parameters.model_fields
                      if k in parameters and _finite(parameters[k])}
        return path[-2], {'controller': controller}
    if path[-1] == 'Rows' and {'weights', 'priority'} <= set(parameters):
        return path[-2], {'weights': list(parameters['weights']), 'priority': parameters['priority']}
    if {'threshold', 'condition'} <= set(parameters):
        return path[-1], {'threshold': parameters['threshold']}
    raise ValueError(f"{node}: a named configuration sets a Task's controller (its CC), weights and priority "
                     "(its Rows) or a Monitor's threshold; this node is none of them")


def configuration_of(dump: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """The named configuration (target -> settings) that sets what ``dump`` (``ros2 param dump``:
    node -> ``ros__parameters``) holds; ValueError naming the node that a configuration cannot set."""
    if not isinstance(dump, dict) or not dump:
        raise ValueError('expected the output of ros2 param dump: node name -> ros__parameters')
    configuration: dict[str, dict[str, Any]] = {}
    for node, content in dump.items():
        if not isinstance(content, dict) or not isinstance(content.get(ROS_PARAMETERS), dict):
            raise ValueError(f'{node}: expected {ROS_PARAMETERS}')
        target, settings = _settings(str(node), content[ROS_PARAMETERS])
        merged = {**configuration.get(target, {}), **settings}
        Settings.model_validate(merged)  # what the model file would take
        configuration[target] = merged
    return configuration

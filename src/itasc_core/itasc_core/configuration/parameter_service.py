"""The parameters of a composite's entities, served by its Configurator (paper §5: the Configurator
is the entity that configures the others).

rclpy gives a node with parameters six services of its own (``~/set_parameters`` and the others
``ros2 param`` calls): twelve DDS endpoints per entity, and Fast DDS matches every new endpoint of
a process against all it holds, so a program's bring-up grew with the square of its entities
(``bench/bench_endpoints.py``). Entities therefore offer none; their composite's Configurator offers
the six once and serves each entity's parameters as ``<entity>.<parameter>``::

    ros2 param set /app/itasc/ApproachObject/configurator CC.kp 2.0
    ros2 param dump /app/itasc/ApproachObject/configurator

Each request is answered by the entity itself, as its own services would have: rclpy's checks of
type, range and read-only, then the entity's parameter model; a refusal's reason reaches the caller
and the recording (``e_<entity>_parameter_refused``), a change is raised as
``e_<entity>_parameter_set``. A change, this way or by a named configuration, is also announced on
``/parameter_events`` as the Configurator's own (:meth:`EntityParameters.announce`), so that what
lists the parameters with its services and follows them there (rqt_reconfigure, Foxglove's parameter
panel, rclpy's ``ParameterEventHandler``) sees it live.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from typing import Callable

from rcl_interfaces.msg import ListParametersResult, ParameterEvent, SetParametersResult
from rcl_interfaces.srv import (DescribeParameters, GetParameters, GetParameterTypes, ListParameters,
                                SetParameters, SetParametersAtomically)
from rclpy.exceptions import ParameterNotDeclaredException
from rclpy.node import Node
from rclpy.parameter import PARAMETER_SEPARATOR_STRING, Parameter
from rclpy.qos import qos_profile_parameter_events, qos_profile_parameters

from ..computation.functional_entity import FunctionalEntity

__all__ = ['EntityParameters', 'listed']


def listed(names: list[str], prefixes: list[str], depth: int) -> ListParametersResult:
    """``names`` filtered as rclpy's ``Node.list_parameters`` filters a node's (a ``~/list_parameters``
    request's ``prefixes`` and ``depth``)."""
    result = ListParametersResult()
    recursive = not prefixes and depth == ListParameters.Request.DEPTH_RECURSIVE

    def shallow(name: str) -> bool:
        return depth == ListParameters.Request.DEPTH_RECURSIVE or name.count(PARAMETER_SEPARATOR_STRING) < depth

    def under(name: str, prefix: str) -> bool:
        return name.startswith(prefix + PARAMETER_SEPARATOR_STRING) and shallow(name[len(prefix) + 1:])

    for name in names:
        if not recursive and not (not prefixes and shallow(name)) and not any(
                name == prefix or under(name, prefix) for prefix in prefixes):
            continue
        result.names.append(name)
        prefix, separator, _ = name.rpartition(PARAMETER_SEPARATOR_STRING)
        if separator and prefix not in result.prefixes:
            result.prefixes.append(prefix)
    return result


class EntityParameters:
    """rclpy's six parameter services, made on ``node`` (the Configurator), for the parameters of
    the entities ``entities()`` returns (name -> entity, as deployed now: re-composition included)."""

    def __init__(self, node: Node, *, entities: Callable[[], Mapping[str, FunctionalEntity]]) -> None:
        self._entities = entities
        self._node = node
        self._composite = node.get_namespace()
        self._events = node.create_publisher(ParameterEvent, '/parameter_events', qos_profile_parameter_events)
        for kind, name, callback in (
                (DescribeParameters, 'describe_parameters', self._describe),
                (GetParameters, 'get_parameters', self._get),
                (GetParameterTypes, 'get_parameter_types', self._get_types),
                (ListParameters, 'list_parameters', self._list),
                (SetParameters, 'set_parameters', self._set),
                (SetParametersAtomically, 'set_parameters_atomically', self._set_atomically)):
            node.create_service(kind, f'~/{name}', callback, qos_profile=qos_profile_parameters)

    def announce(self, entity: str, parameters: list[Parameter]) -> None:
        """Tell ``/parameter_events`` that the entity ``entity`` took ``parameters`` (its own names),
        as the change of ``<entity>.<parameter>`` on the Configurator's node."""
        if not parameters:
            return
        self._events.publish(ParameterEvent(
            stamp=self._node.get_clock().now().to_msg(), node=self._node.get_fully_qualified_name(),
            changed_parameters=[Parameter(f'{entity}{PARAMETER_SEPARATOR_STRING}{p.name}', p.type_, p.value)
                                .to_parameter_msg() for p in parameters]))

    def _owner(self, name: str) -> tuple[FunctionalEntity, str] | None:
        """The entity that holds the parameter ``<entity>.<parameter>``, and its own name for it."""
        entity_name, _, parameter = name.partition(PARAMETER_SEPARATOR_STRING)
        entity = self._entities().get(entity_name)
        if entity is None or parameter not in entity.parameter_names:
            return None
        return entity, parameter

    def _unknown(self, name: str) -> str:
        with_parameters = sorted(n for n, e in self._entities().items() if e.parameter_names)
        return (f"no parameter '{name}' in composite {self._composite}: parameters are named "
                f"<entity>.<parameter>, entities {with_parameters}")

    def _owners(self, names) -> list[tuple[FunctionalEntity, str]]:
        """The owner of every parameter of ``names``; none at all if one is unknown (rclpy's services
        answer a request naming an unknown parameter with no values)."""
        owners = [self._owner(name) for name in names]
        return [] if None in owners else owners  # type: ignore[return-value]

    def _describe(self, request, response):
        for name, (entity, own) in zip(request.names, self._owners(request.names)):
            descriptor = copy.deepcopy(entity.describe_parameter(own))
            descriptor.name = name
            response.descriptors.append(descriptor)
        return response

    def _get(self, request, response):
        response.values = [entity.get_parameter(p).get_parameter_value() for entity, p in self._owners(request.names)]
        return response

    def _get_types(self, request, response):
        response.types = [entity.get_parameter_type(p) for entity, p in self._owners(request.names)]
        return response

    def _list(self, request, response):
        names = [f'{e}{PARAMETER_SEPARATOR_STRING}{p}'
                 for e, entity in sorted(self._entities().items()) for p in entity.parameter_names]
        response.result = listed(names, list(request.prefixes), request.depth)
        return response

    def _set_one_entity(self, parameters: list[Parameter]) -> SetParametersResult:
        """``parameters`` (full names, all of one entity) set atomically by that entity."""
        if not parameters:
            return SetParametersResult(successful=True)
        owners = [self._owner(p.name) for p in parameters]
        known = [owner for owner in owners if owner is not None]
        if len(known) < len(parameters):
            missing = next(p.name for p, owner in zip(parameters, owners) if owner is None)
            return SetParametersResult(successful=False, reason=self._unknown(missing))
        entity = known[0][0]
        own = [Parameter(name, p.type_, p.value) for p, (_, name) in zip(parameters, known)]
        try:
            result = entity.set_parameters_atomically(own)
        except ParameterNotDeclaredException as err:
            return SetParametersResult(successful=False, reason=str(err))
        if result.successful:
            self.announce(entity.entity_name, own)
        return result

    def _set(self, request, response):
        response.results = [self._set_one_entity([Parameter.from_parameter_msg(p)]) for p in request.parameters]
        return response

    def _set_atomically(self, request, response):
        parameters = [Parameter.from_parameter_msg(p) for p in request.parameters]
        entities = sorted({p.name.partition(PARAMETER_SEPARATOR_STRING)[0] for p in parameters})
        if len(entities) > 1:
            response.result = SetParametersResult(
                successful=False, reason=f'parameters of {len(entities)} entities ({", ".join(entities)}): '
                'each entity takes its own atomically, set them one entity at a time')
        else:
            response.result = self._set_one_entity(parameters)
        return response

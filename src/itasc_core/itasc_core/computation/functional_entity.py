"""Functional Entities: the computations of a composite (paper §4).

A Functional Entity declares its ports with metadata (paper Listing 1) as a pure function of its
parameters, so that a Composer can check connections from the model alone, in any process. Its
parameters are ROS 2 parameters, typed by one pydantic model per kind (:mod:`.parameters`), set by
the Configurator or from outside (``ros2 param set`` through the Configurator's services,
:mod:`..configuration.parameter_service`), every change and refusal raised as an event;
its ``update`` is called by the Scheduler. It knows no other entity: it reads
its input ports, writes its output ports and raises events (§3.1, boundary of knowledge).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from typing import Any, ClassVar

from pydantic import ValidationError
from rcl_interfaces.msg import SetParametersResult
from rclpy.parameter import Parameter

from ..communication.event_names import PARAMETER_REFUSED, PARAMETER_SET, SAFETY_EVENT, event
from ..communication.ports import InputPort, OutputPort, PortSpec
from ..entity import CompositeContext, Entity
from ..kinds import UnknownKind
from .parameters import NoParameters, ParameterModel, declarations, flatten, nest, problems

__all__ = ['FunctionalEntity', 'OUTSIDE']


#: Who set parameters that no configuration of the model set (``ros2 param set``, an operator's tool).
OUTSIDE = 'set from outside'


class FunctionalEntity(Entity):
    """Base class of every leaf Functional Entity.

    Subclasses set :attr:`Parameters` (their parameter model), implement :meth:`port_specs`,
    :meth:`configure` (take the parameters into use) and :meth:`update`.
    """

    #: The model of the entity's parameters (:mod:`.parameters`).
    Parameters: ClassVar[type[ParameterModel]] = NoParameters
    #: Who sets parameters now (see :meth:`set_by`).
    cause: str = OUTSIDE

    def __init__(self, name: str, *, composite: CompositeContext, parameters: Mapping[str, Any] | None = None) -> None:
        super().__init__(name, composite=composite)
        self.inputs: dict[str, InputPort] = {}
        self.outputs: dict[str, OutputPort] = {}
        try:
            try:
                values = self.parameters_of(parameters or {})
            except (ValidationError, UnknownKind) as err:
                raise ValueError(f'{type(self).__name__} {name}: {problems(err)}') from None
            self._types: dict[str, Parameter.Type] = {}
            #: The node's own parameters (rclpy's ``use_sim_time``): rclpy's to check, not the model's.
            self._node_parameters = frozenset(self.list_parameters([], 0).names)
            for key, value, descriptor in declarations(values):
                self._types[key] = Parameter.Type(descriptor.type)
                if isinstance(value, list) and not value:  # an empty list has no type of its own
                    read_only, descriptor.read_only = descriptor.read_only, False
                    self.declare_parameter(key, self._types[key], descriptor)
                    (result,) = self.set_parameters([Parameter(key, self._types[key], [])])
                    if not result.successful:
                        raise ValueError(f'{key}: {result.reason}')
                    # rclpy keeps this descriptor (describe_parameter returns it): read-only from now on
                    self.describe_parameter(key).read_only = read_only
                else:
                    self.declare_parameter(key, value, descriptor)
            self.params = values
            for spec in self.port_specs(values):
                topic = self.port_topic(composite.namespace, name, spec.name)
                if spec.direction == 'input':
                    self.inputs[spec.name] = InputPort(self, spec.with_id(topic))
                else:
                    self.outputs[spec.name] = OutputPort(self, spec.with_id(topic))
            self.add_on_set_parameters_callback(self._check_parameters)
            self.add_post_set_parameters_callback(self._parameters_set)
            self.configure(values)
        except BaseException:
            self.destroy_node()  # a node that failed to construct must not stay in the graph
            raise

    @property
    def parameter_names(self) -> list[str]:
        """The entity's parameters (its parameter model's fields, nested ones dotted)."""
        return list(self._types)

    @staticmethod
    def port_topic(namespace: str, entity: str, port: str) -> str:
        return f'{namespace}/{entity}/{port}'

    @classmethod
    def port_specs(cls, params: Any) -> list[PortSpec]:
        """The entity's ports (metadata only) for the given parameters."""
        return []

    # -- configuration ----------------------------------------------------------------------------

    @classmethod
    def parameter_model(cls, values: Mapping[str, Any]) -> type[ParameterModel]:
        """The model that validates ``values`` (a kind whose parameters depend on one of them, e.g.
        a chain's type, chooses here)."""
        return cls.Parameters

    @classmethod
    def parameters_of(cls, values: Mapping[str, Any]) -> ParameterModel:
        """``values`` (a model's ``parameters``, nested) validated; raises pydantic's ValidationError."""
        return cls.parameter_model(values).model_validate(values)

    def ros_parameters(self, changes: Mapping[str, Any]) -> list[Parameter]:
        """``changes`` (dotted names -> values, e.g. a named configuration's) as typed ROS parameters,
        checked against the model with the entity's other values; ValueError says why they do not fit."""
        current = flatten(self.params)
        unknown = sorted(set(changes) - set(current))
        if unknown:
            raise ValueError(f'no parameters {unknown}; parameters: {sorted(current)}')
        try:
            proposed = flatten(self.parameters_of(nest({**current, **changes})))
        except (ValidationError, UnknownKind) as err:
            raise ValueError(problems(err)) from None
        return [Parameter(key, self._types[key], proposed[key]) for key in changes]

    def set_parameters(self, parameter_list: list[Parameter]) -> list[SetParametersResult]:
        """rclpy's, with every refusal raised as ``e_<entity>_parameter_refused`` (see :meth:`_refused`)."""
        results = super().set_parameters(parameter_list)
        for parameter, result in zip(parameter_list, results):
            self._refused([parameter], result)
        return results

    def set_parameters_atomically(self, parameter_list: list[Parameter]) -> SetParametersResult:
        """rclpy's (what a ``~/set_parameters`` request, ``ros2 param set``, runs), with a refusal
        raised as ``e_<entity>_parameter_refused``."""
        result = super().set_parameters_atomically(parameter_list)
        self._refused(parameter_list, result)
        return result

    def _refused(self, parameters: list[Parameter], result: SetParametersResult) -> None:
        """A change refused by rclpy (the declared type and range) or by the parameter model
        (:meth:`_check_parameters`) goes into the recording: detail ``<parameters>: <why> (<cause>)``."""
        if not result.successful:
            names = ', '.join(f'{p.name} = {p.value!r}' for p in parameters)
            self.raise_event(event(self.entity_name, PARAMETER_REFUSED),
                             detail=f'{names}: {result.reason} ({self.cause})')

    def _check_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        """Checked by the parameter model, then taken into use (:meth:`configure`): what only the
        entity can tell (a frame its Scene does not have) refuses the change too, and the entity
        goes on with the values it had. rclpy has checked type, range and read-only before, and
        stores the values only after this says yes. The node's own parameters are left to rclpy
        (``set_parameters([Parameter('use_sim_time', value=True)])`` on the entity's node switches
        its clock to ``/clock``; the entities serve no parameter services, their Configurator serves
        the model's parameters only)."""
        parameters = [p for p in parameters if p.name not in self._node_parameters]
        if not parameters:
            self._configured = self.params
            return SetParametersResult(successful=True)
        current = flatten(self.params)
        infinite = [p.name for p in parameters if _newly_infinite(current.get(p.name), p.value)]
        if infinite:  # as in a model file; an infinity the model gave (a joint unbounded in its URDF) may stay
            return SetParametersResult(successful=False, reason=f'{", ".join(infinite)}: not a finite number '
                                       '(infinite where it was finite)')
        proposed = current | {p.name: p.value for p in parameters}
        try:
            values = self.parameters_of(nest(proposed))
        except (ValidationError, UnknownKind) as err:
            return SetParametersResult(successful=False, reason=problems(err))
        try:
            self.configure(values)
        except Exception as err:  # noqa: BLE001 - any reason of the entity's refuses the change
            reason = f'{type(err).__name__}: {err}'
            try:
                self.configure(self.params)
            except Exception as again:  # noqa: BLE001 - an entity that cannot go back is not fit to run
                self.raise_event(SAFETY_EVENT, priority=True, detail=f'{self.entity_name} could not take back its '
                                 f'parameters after refusing a change ({reason}): {type(again).__name__}: {again}')
            return SetParametersResult(successful=False, reason=reason)
        self._configured = values
        return SetParametersResult(successful=True)

    def _parameters_set(self, parameters: list[Parameter]) -> None:
        """Taken into use at once (in an executor callback: between two ticks, by
        :meth:`_check_parameters`), and raised as ``e_<entity>_parameter_set`` per parameter that
        changed (detail ``kp: 1.0 -> 2.0 (<cause>)``), so that the recording holds every change."""
        before = flatten(self.params)
        self.params = self._configured
        after = flatten(self.params)
        for name in [p.name for p in parameters if before.get(p.name) != after.get(p.name)]:
            self.raise_event(event(self.entity_name, PARAMETER_SET),
                             detail=f'{name}: {before.get(name)!r} -> {after[name]!r} ({self.cause})')

    @contextmanager
    def set_by(self, cause: str) -> Iterator[None]:
        """Parameters set within the block are ``cause``'s (e.g. a named configuration), not
        someone's outside (``ros2 param set``)."""
        self.cause, previous = cause, self.cause
        try:
            yield
        finally:
            self.cause = previous

    def configure(self, params: Any) -> None:
        """Take (new) parameter values into use."""

    # -- life cycle, driven by the Scheduler ----------------------------------------------------------

    def start(self) -> None:
        """Prepare for computation (Starting)."""

    def update(self, t: float) -> None:
        """One computation step at time ``t`` (seconds since the Timer started)."""

    def activate(self) -> None:
        """Switched on again by the Coordinator (``e_<entity or its composite>_activate``) after
        being off: continue from the present, not from where it stopped (e.g. a setpoint
        generator restarts from the current output)."""

    def deactivate(self, t: float) -> None:
        """Switched off by the Coordinator (``e_<entity or its composite>_deactivate``) at ``t``
        (between two ticks, in their time): no more ticks until it is switched on again. Whoever
        reads its outputs must learn that what it last wrote no longer holds (e.g. a Task's rows
        leave the Solver's problem), wherever they are read: in another process, the last sample
        would otherwise simply come no more."""

    def disengage(self) -> None:
        """Stop acting on the world (Stopped.Disengage), e.g. command zero velocity."""

    def safe(self) -> None:
        """Bring outputs to a safe value (Safety)."""
        self.disengage()

    def fault_persists(self) -> str | None:
        """Asked before a recovery from Safety when this entity raised one of its faults: why its
        condition still holds, on the data that came in since, or None if it no longer does (the
        default: an entity that cannot tell lets the restart test it, see
        :mod:`..coordination.recovery`)."""
        return None

    def destroy_node(self) -> None:
        for port in self.inputs.values():
            port.disconnect()
        for output in self.outputs.values():
            output.destroy()
        super().destroy_node()


def _newly_infinite(old: Any, new: Any) -> bool:
    """Whether ``new`` (a parameter's value) holds an infinity where ``old`` did not hold the same."""
    if isinstance(new, float):
        return math.isinf(new) and new != old
    if isinstance(new, Sequence) and not isinstance(new, (str, bytes)):  # a ROS array: array.array, list
        before = list(old) if isinstance(old, Sequence) and not isinstance(old, (str, bytes)) else []
        return any(isinstance(v, float) and math.isinf(v) and (i >= len(before) or before[i] != v)
                   for i, v in enumerate(new))
    return False

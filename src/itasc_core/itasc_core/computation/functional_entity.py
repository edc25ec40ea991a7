"""Functional Entities: the computations of a composite (paper §4).

A Functional Entity declares its ports with metadata (paper Listing 1) as a pure function of its
parameters, so that a Composer can check connections from the model alone, in any process. Its
parameters are ROS 2 parameters, set by the Configurator; its ``update`` is called by the
Scheduler. It knows no other entity: it reads its input ports, writes its output ports and raises
events (§3.1, boundary of knowledge).
"""

from __future__ import annotations

from typing import Any, ClassVar

from rcl_interfaces.msg import SetParametersResult
from rclpy.parameter import Parameter

from ..communication.ports import InputPort, OutputPort, PortSpec
from ..entity import CompositeContext, Entity

__all__ = ['FunctionalEntity', 'coerce']


def coerce(default: Any, value: Any) -> Any:
    """Match a model value to the parameter's declared type (YAML writes 1 for 1.0)."""
    if isinstance(default, float) and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if isinstance(default, list) and default and isinstance(default[0], float) and isinstance(value, list):
        return [float(v) for v in value]
    return value


class FunctionalEntity(Entity):
    """Base class of every leaf Functional Entity.

    Subclasses set :attr:`PARAMETERS` (name -> default), implement :meth:`port_specs`,
    :meth:`configure` (read parameters into attributes) and :meth:`update`.
    """

    #: ROS parameters of the entity and their defaults.
    PARAMETERS: ClassVar[dict[str, Any]] = {}

    def __init__(self, name: str, *, composite: CompositeContext, parameters: dict[str, Any] | None = None) -> None:
        super().__init__(name, composite=composite)
        self.inputs: dict[str, InputPort] = {}
        self.outputs: dict[str, OutputPort] = {}
        try:
            values = dict(self.PARAMETERS)
            values.update({k: coerce(self.PARAMETERS.get(k), v) for k, v in (parameters or {}).items()})
            unknown = set(values) - set(self.PARAMETERS)
            if unknown:
                raise ValueError(f'{type(self).__name__} {name}: unknown parameters {sorted(unknown)}; '
                                 f'known: {sorted(self.PARAMETERS)}')
            for key, value in values.items():
                self.declare_parameter(key, value)
            self.params: dict[str, Any] = values
            for spec in self.port_specs(values):
                topic = self.port_topic(composite.namespace, name, spec.name)
                if spec.direction == 'input':
                    self.inputs[spec.name] = InputPort(self, spec.with_id(topic))
                else:
                    self.outputs[spec.name] = OutputPort(self, spec.with_id(topic))
            reason = self.validate_parameters(values)
            if reason:  # later changes are checked by _check_parameters
                raise ValueError(f'{type(self).__name__} {name}: {reason}')
            self.add_on_set_parameters_callback(self._check_parameters)
            self.add_post_set_parameters_callback(self._parameters_set)
            self.configure(values)
        except BaseException:
            self.destroy_node()  # a node that failed to construct must not stay in the graph
            raise

    @staticmethod
    def port_topic(namespace: str, entity: str, port: str) -> str:
        return f'{namespace}/{entity}/{port}'

    @classmethod
    def port_specs(cls, params: dict[str, Any]) -> list[PortSpec]:
        """The entity's ports (metadata only) for the given parameters."""
        return []

    # -- configuration ----------------------------------------------------------------------------

    def validate_parameters(self, params: dict[str, Any]) -> str | None:
        """Return why ``params`` are unacceptable, or None."""
        return None

    def _check_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        proposed = dict(self.params)
        proposed.update({p.name: p.value for p in parameters})
        unknown = sorted(set(proposed) - set(self.PARAMETERS))
        if unknown:
            return SetParametersResult(successful=False, reason=f'unknown parameters {unknown}')
        reason = self.validate_parameters(proposed)
        return SetParametersResult(successful=reason is None, reason=reason or '')

    def _parameters_set(self, parameters: list[Parameter]) -> None:
        self.params.update({p.name: p.value for p in parameters})
        self.configure(self.params)

    def configure(self, params: dict[str, Any]) -> None:
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
        for port in self.outputs.values():
            port.destroy()
        super().destroy_node()

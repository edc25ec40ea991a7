"""A small library of generic Functional Entities on ``std_msgs/Float64MultiArray`` signals
(paper §4.1: setpoint generators, controllers, a plant stand-in), used by the model of the pattern
itself (``config/apps/pattern_demo.yaml``) and by the runtime's tests.
"""

from __future__ import annotations

import math
from pydantic import Field
from std_msgs.msg import Float64MultiArray

from ..communication.ports import PortSpec
from .functional_entity import FunctionalEntity
from .parameters import ParameterModel

__all__ = ['SineSource', 'PController', 'Integrator', 'Sum']


def _signal(name: str, direction: str, semantics: str, *, multiple: bool = False) -> PortSpec:
    return PortSpec(name=name, direction=direction, msg_type=Float64MultiArray, type='signal',
                    semantics=semantics, multiple=multiple)


def _msg(values: list[float]) -> Float64MultiArray:
    msg = Float64MultiArray()
    msg.data = values
    return msg


class SineSource(FunctionalEntity):
    """A periodic setpoint generator: ``offset + amplitude * sin(2π f t)`` on ``size`` channels."""

    class Parameters(ParameterModel):
        amplitude: float = 1.0
        """Amplitude of the sine."""
        frequency: float = Field(default=0.5, ge=0)
        """Frequency [Hz]."""
        offset: float = 0.0
        """Centre of the sine."""
        size: int = Field(default=1, ge=1)
        """Number of channels."""
        semantics: str = 'Position(x)'
        """Semantics of the output port."""

    @classmethod
    def port_specs(cls, params: Parameters) -> list[PortSpec]:
        return [_signal('signal', 'output', params.semantics)]

    def configure(self, params: Parameters) -> None:
        self.amplitude, self.frequency = params.amplitude, params.frequency
        self.offset, self.size = params.offset, params.size

    def update(self, t: float) -> None:
        value = self.offset + self.amplitude * math.sin(2.0 * math.pi * self.frequency * t)
        self.outputs['signal'].write(_msg([value] * self.size))


class PController(FunctionalEntity):
    """A proportional constraint controller with saturation: ``u = sat(kp (setpoint - measured))``."""

    class Parameters(ParameterModel):
        kp: float = Field(default=1.0, ge=0)
        """Proportional gain [1/s]."""
        max_output: float = Field(default=10.0, gt=0)
        """Saturation of the command."""
        semantics: str = 'Position(x)'
        """Semantics of the setpoint and the measurement."""
        command_semantics: str = 'Velocity(x)'
        """Semantics of the command."""

    @classmethod
    def port_specs(cls, params: Parameters) -> list[PortSpec]:
        return [
            _signal('setpoint', 'input', params.semantics),
            _signal('measured', 'input', params.semantics),
            _signal('command', 'output', params.command_semantics),
            _signal('error', 'output', params.semantics + '.error'),
        ]

    def configure(self, params: Parameters) -> None:
        self.kp, self.max_output = params.kp, params.max_output

    def update(self, t: float) -> None:
        setpoint, measured = self.inputs['setpoint'].latest, self.inputs['measured'].latest
        if setpoint is None:
            return
        current = measured.data if measured is not None else [0.0] * len(setpoint.data)
        error = [s - m for s, m in zip(setpoint.data, current)]
        limit = self.max_output
        command = [max(-limit, min(limit, self.kp * e)) for e in error]
        self.outputs['error'].write(_msg(error))
        self.outputs['command'].write(_msg(command))


class Integrator(FunctionalEntity):
    """A plant stand-in: integrates the commanded rate, ``x += u dt``."""

    class Parameters(ParameterModel):
        size: int = Field(default=1, ge=1)
        """Number of channels."""
        initial: float = 0.0
        """Initial state of every channel."""
        semantics: str = 'Position(x)'
        """Semantics of the state."""
        rate_semantics: str = 'Velocity(x)'
        """Semantics of the rate."""

    @classmethod
    def port_specs(cls, params: Parameters) -> list[PortSpec]:
        return [_signal('rate', 'input', params.rate_semantics), _signal('state', 'output', params.semantics)]

    def configure(self, params: Parameters) -> None:
        if not hasattr(self, 'x'):
            self.x = [params.initial] * params.size
        self._last_t: float | None = None

    def update(self, t: float) -> None:
        rate = self.inputs['rate'].latest
        if rate is not None and self._last_t is not None:
            dt = t - self._last_t
            self.x = [x + u * dt for x, u in zip(self.x, rate.data)]
        self._last_t = t
        self.outputs['state'].write(_msg(list(self.x)))


class Sum(FunctionalEntity):
    """Adds the newest sample of every connected source."""

    class Parameters(ParameterModel):
        size: int = Field(default=1, ge=1)
        """Number of channels."""
        semantics: str = 'Velocity(x)'
        """Semantics of the inputs and the sum."""

    @classmethod
    def port_specs(cls, params: Parameters) -> list[PortSpec]:
        return [_signal('inputs', 'input', params.semantics, multiple=True),
                _signal('sum', 'output', params.semantics)]

    def configure(self, params: Parameters) -> None:
        self.size = params.size

    def update(self, t: float) -> None:
        total = [0.0] * self.size
        for sample in self.inputs['inputs'].samples.values():
            total = [a + b for a, b in zip(total, sample.data)]
        self.outputs['sum'].write(_msg(total))

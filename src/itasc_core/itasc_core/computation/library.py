"""A small library of generic Functional Entities on ``std_msgs/Float64MultiArray`` signals
(paper §4.1: setpoint generators, controllers, a plant stand-in), used by the model of the pattern
itself (``config/apps/pattern_demo.yaml``) and by the runtime's tests.
"""

from __future__ import annotations

import math
from typing import Any

from std_msgs.msg import Float64MultiArray

from ..communication.ports import PortSpec
from .functional_entity import FunctionalEntity

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

    PARAMETERS = {'amplitude': 1.0, 'frequency': 0.5, 'offset': 0.0, 'size': 1, 'semantics': 'Position(x)'}

    @classmethod
    def port_specs(cls, params: dict[str, Any]) -> list[PortSpec]:
        return [_signal('signal', 'output', params['semantics'])]

    def configure(self, params: dict[str, Any]) -> None:
        self.amplitude, self.frequency = params['amplitude'], params['frequency']
        self.offset, self.size = params['offset'], params['size']

    def update(self, t: float) -> None:
        value = self.offset + self.amplitude * math.sin(2.0 * math.pi * self.frequency * t)
        self.outputs['signal'].write(_msg([value] * self.size))


class PController(FunctionalEntity):
    """A proportional constraint controller with saturation: ``u = sat(kp (setpoint - measured))``."""

    PARAMETERS = {'kp': 1.0, 'max_output': 10.0, 'semantics': 'Position(x)', 'command_semantics': 'Velocity(x)'}

    @classmethod
    def port_specs(cls, params: dict[str, Any]) -> list[PortSpec]:
        return [
            _signal('setpoint', 'input', params['semantics']),
            _signal('measured', 'input', params['semantics']),
            _signal('command', 'output', params['command_semantics']),
            _signal('error', 'output', params['semantics'] + '.error'),
        ]

    def validate_parameters(self, params: dict[str, Any]) -> str | None:
        if params['kp'] < 0 or params['max_output'] <= 0:
            return 'kp must be >= 0 and max_output > 0'
        return None

    def configure(self, params: dict[str, Any]) -> None:
        self.kp, self.max_output = params['kp'], params['max_output']

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

    PARAMETERS = {'size': 1, 'initial': 0.0, 'semantics': 'Position(x)', 'rate_semantics': 'Velocity(x)'}

    @classmethod
    def port_specs(cls, params: dict[str, Any]) -> list[PortSpec]:
        return [_signal('rate', 'input', params['rate_semantics']), _signal('state', 'output', params['semantics'])]

    def configure(self, params: dict[str, Any]) -> None:
        if not hasattr(self, 'x'):
            self.x = [params['initial']] * params['size']
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

    PARAMETERS = {'size': 1, 'semantics': 'Velocity(x)'}

    @classmethod
    def port_specs(cls, params: dict[str, Any]) -> list[PortSpec]:
        return [_signal('inputs', 'input', params['semantics'], multiple=True),
                _signal('sum', 'output', params['semantics'])]

    def configure(self, params: dict[str, Any]) -> None:
        self.size = params['size']

    def update(self, t: float) -> None:
        total = [0.0] * self.size
        for sample in self.inputs['inputs'].samples.values():
            total = [a + b for a, b in zip(total, sample.data)]
        self.outputs['sum'].write(_msg(total))

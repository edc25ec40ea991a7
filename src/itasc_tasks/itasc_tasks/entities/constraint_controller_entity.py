"""ConstraintControllerEntity: the Constraint Controller of a Task (paper §4.1 "CC", §4.2,
§5 "Configuration").

Runs the registered control law ``kind`` (:mod:`itasc_tasks.controllers`, e.g. P or PID with
feed-forward and saturation) with the rules of :mod:`itasc_tasks.constraint_controller`. Its
gains (``kp``, ``max_output``, a PID's ``ki``, ``kd``, ...) are ROS parameters, so a named configuration such
as ``high_accuracy_control`` applied by the Task's Configurator switches them at run time (the
integral is kept across a gain switch, cleared when the Task is reactivated).

Equality Task: inputs ``output`` (y) and ``setpoint`` (y_d with its feed-forward velocity),
``equality_control``. Inequality Task (``inequality``: bounds ``lower``/``upper`` on y, e.g.
distance >= d_min): no setpoint, ``inequality_control``. Output ``control``
(``itasc_msgs/Control``): per output ``desired``, ``lower``, ``upper`` (bounds on ydot),
``setpoint`` and ``error``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from pydantic import Field, model_validator

from itasc_core.communication.ports import PortSpec
from itasc_core.computation.functional_entity import FunctionalEntity
from itasc_core.computation.parameters import ParameterModel
from itasc_core.itasc.entities.messages import ControlSample
from itasc_core.kinds import with_kind

from ..constraint_controller import equality_control, inequality_control
from ..controllers import CONTROLLERS, ConstraintController
from .common import TaskName, Ticks, task_port

__all__ = ['ConstraintControllerEntity', 'ControllerBase']


class ControllerBase(ParameterModel):
    """A Constraint Controller (paper §4.1 "CC"): a registered control law and its gains."""

    kind: str = 'pid'
    """The control law: a registered controller (``p``: proportional; ``pid``: proportional,
    integral, derivative; its gains follow)."""


class ConstraintControllerEntity(FunctionalEntity):
    """Desired output velocity (or its bounds) from the output and its setpoint."""

    class Parameters(ControllerBase):
        task: TaskName = 'task'
        """The Task it belongs to."""
        tick_period: float = Field(default=0.01, gt=0)
        """The program's nominal tick period [s]."""
        inequality: bool = Field(default=False, frozen=True)
        """Bounds on the output (``lower``/``upper``) instead of a setpoint (what the Task is: fixed)."""
        lower: list[float] = Field(default_factory=lambda: [-math.inf])
        """Inequality: lower bound on the output, one value or one per output."""
        upper: list[float] = Field(default_factory=lambda: [math.inf])
        """Inequality: upper bound on the output, one value or one per output."""

        @model_validator(mode='after')
        def _bounds(self) -> 'ConstraintControllerEntity.Parameters':
            lower, upper = np.asarray(self.lower, dtype=float), np.asarray(self.upper, dtype=float)
            if lower.size == upper.size or 1 in (lower.size, upper.size):
                crossed = np.flatnonzero(np.broadcast_to(lower > upper, (max(lower.size, upper.size),)))
                if crossed.size:
                    raise ValueError(f'lower is above upper (output {", ".join(map(str, crossed))})')
            return self

    @classmethod
    def parameter_model(cls, values: Mapping[str, Any]) -> type[ParameterModel]:
        return with_kind(cls.Parameters, CONTROLLERS, field='kind', values=values)

    @classmethod
    def port_specs(cls, params: Any) -> list[PortSpec]:
        task = params.task
        specs = [task_port('output', 'input', 'Output', task)]
        if not params.inequality:
            specs.append(task_port('setpoint', 'input', 'Setpoint', task))
        return specs + [task_port('control', 'output', 'Control', task)]

    def configure(self, params: Any) -> None:
        if not hasattr(self, 'controller'):  # a gain changed: the law keeps its state (the integral)
            self.controller: ConstraintController = CONTROLLERS[params.kind]()
        self.controller.configure(params)
        self.inequality = params.inequality
        self.lower = np.asarray(params.lower, dtype=float)
        self.upper = np.asarray(params.upper, dtype=float)
        self._ticks = getattr(self, '_ticks', None) or Ticks(params.tick_period)
        self._ticks.period = params.tick_period

    def start(self) -> None:
        """Starting (also again, after a recovery from Safety): the next tick starts afresh (the
        integral of the error reset)."""
        self._ticks.reset()

    def activate(self) -> None:
        self._ticks.restart()

    def update(self, t: float) -> None:
        output = self.inputs['output'].latest
        if output is None:
            return
        dt, resumed = self._ticks.step(t)
        if resumed:
            self.controller.reset()
        if self.inequality:
            control = inequality_control(output.value, lower=self.lower, upper=self.upper, kp=self.controller.kp)
        else:
            setpoint = self.inputs['setpoint'].latest
            if setpoint is None:
                return
            if setpoint.names != output.names:
                raise ValueError(f'setpoint rows {setpoint.names} do not match outputs {output.names}')
            control = equality_control(self.controller, output.value, setpoint.value, setpoint.velocity, dt,
                                       rotation=output.rotation)
        desired, lower, upper, setpoint_value, error = control
        self.outputs['control'].write(ControlSample(t, output.names, desired=desired, lower=lower, upper=upper,
                                                    setpoint=setpoint_value, error=error))

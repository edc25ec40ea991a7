"""ConstraintControllerEntity: the Constraint Controller of a Task (paper §4.1 "CC", §4.2,
§5 "Configuration").

Wraps :mod:`itasc_tasks.constraint_controller` (P or PID with feed-forward and saturation). Its
gains ``kp``, ``ki``, ``kd`` and ``max_output`` are ROS parameters, so a named configuration such
as ``high_accuracy_control`` applied by the Task's Configurator switches them at run time (the
integral is kept across a gain switch, cleared when the Task is reactivated).

Equality Task: inputs ``output`` (y) and ``setpoint`` (y_d with its feed-forward velocity);
``desired = sat(ff + PID(e))``. Inequality Task (``inequality``: bounds ``lower``/``upper`` on y,
e.g. distance >= d_min): no setpoint; ``kp (lower - y) <= ydot <= kp (upper - y)``, so a violated
bound is recovered at rate kp. Output ``control``: a labelled table with one row per output and
columns ``desired``, ``lower``, ``upper`` (bounds on ydot), ``setpoint`` and ``error``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from itasc_core.communication.ports import PortSpec
from itasc_core.computation.functional_entity import FunctionalEntity
from itasc_core.itasc.entities.messages import read_table, table_msg

from ..constraint_controller import PController, PIDController
from .common import Ticks, table_port

__all__ = ['ConstraintControllerEntity', 'CONTROL_COLUMNS']

CONTROL_COLUMNS = ('desired', 'lower', 'upper', 'setpoint', 'error')


class ConstraintControllerEntity(FunctionalEntity):
    """Desired output velocity (or its bounds) from the output and its setpoint."""

    PARAMETERS = {
        'task': 'task',
        'tick_period': 0.01,      # the program's nominal tick period [s]
        'kind': 'pid',            # p | pid
        'kp': 1.0,
        'ki': 0.0,
        'kd': 0.0,
        'max_output': math.inf,   # saturation of each component of ydot
        'max_integral': math.inf,
        'inequality': False,
        'lower': [-math.inf],     # inequality: bounds on y (one value, or one per output)
        'upper': [math.inf],
    }

    @classmethod
    def port_specs(cls, params: dict[str, Any]) -> list[PortSpec]:
        task = params['task']
        specs = [table_port('output', 'input', 'Output', task)]
        if not params['inequality']:
            specs.append(table_port('setpoint', 'input', 'Setpoint', task))
        return specs + [table_port('control', 'output', 'Control', task)]

    def validate_parameters(self, params: dict[str, Any]) -> str | None:
        if params['kind'] not in ('p', 'pid'):
            return f"kind must be 'p' or 'pid', got {params['kind']!r}"
        if min(params['kp'], params['ki'], params['kd']) < 0 or params['max_output'] <= 0 \
                or params['max_integral'] <= 0:
            return 'gains must be >= 0 and max_output, max_integral > 0'
        return None

    def configure(self, params: dict[str, Any]) -> None:
        cls = PIDController if params['kind'] == 'pid' else PController
        if type(getattr(self, 'controller', None)) is not cls:
            self.controller = cls()
        self.controller.kp, self.controller.max_output = params['kp'], params['max_output']
        if isinstance(self.controller, PIDController):
            self.controller.ki, self.controller.kd = params['ki'], params['kd']
            self.controller.max_integral = params['max_integral']
        self.inequality = params['inequality']
        self.lower = np.asarray(params['lower'], dtype=float)
        self.upper = np.asarray(params['upper'], dtype=float)
        self._ticks = getattr(self, '_ticks', None) or Ticks(params['tick_period'])
        self._ticks.period = params['tick_period']

    def start(self) -> None:
        """Starting (also again, after a recovery from Safety): the next tick starts afresh (the
        integral of the error reset)."""
        self._ticks.reset()

    def activate(self) -> None:
        self._ticks.restart()

    def update(self, t: float) -> None:
        msg = self.inputs['output'].latest
        if msg is None:
            return
        output = read_table(msg)
        y = output.column('value')
        dt, resumed = self._ticks.step(t)
        if resumed:
            self.controller.reset()
        if self.inequality:
            kp = self.controller.kp
            lower, upper = kp * (self.lower - y), kp * (self.upper - y)
            setpoint = np.clip(y, self.lower, self.upper)
            columns = [np.zeros_like(y), lower, upper, setpoint, setpoint - y]
        else:
            sp = self.inputs['setpoint'].latest
            if sp is None:
                return
            setpoint = read_table(sp)
            if setpoint.rows != output.rows:
                raise ValueError(f'setpoint rows {setpoint.rows} do not match outputs {output.rows}')
            r = output.rotation
            self.controller.rotation = slice(r, r + 3) if r is not None else None
            y_d = setpoint.column('value')
            desired = self.controller(y, y_d, setpoint.column('velocity'), dt)
            columns = [desired, desired, desired, y_d, self.controller.error]
        values = np.column_stack([np.broadcast_to(c, y.shape) for c in columns])
        self.outputs['control'].write(table_msg(output.rows, CONTROL_COLUMNS, values))

"""ConstraintRowsEntity: what a Task hands to the Solver and to its observers (paper §4.2
"Task": "delivering a set of constraints to the optimization problem", Fig. 2).

It joins the Constraint Output's Jacobian J_y with the Constraint Controller's desired output
velocity (or bounds), the Task's row ``weights`` and ``priority`` into ``itasc_msgs/ConstraintRows``
(port ``rows``), and publishes what the Task sees, ``itasc_msgs/TaskState`` (output y, setpoint,
error and its norm; port ``state``) for Monitors, recordings and plots.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from itasc_msgs.msg import ConstraintRows, TaskState

from itasc_core.communication.ports import PortSpec
from itasc_core.computation.functional_entity import FunctionalEntity
from itasc_core.itasc.entities.messages import read_table, stamp
from itasc_core.itasc.entities.solver_entity import ROWS_SEMANTICS

from .common import table_port

__all__ = ['ConstraintRowsEntity']


class ConstraintRowsEntity(FunctionalEntity):
    """The Task's constraint rows on the program-wide joint velocities, and its state."""

    PARAMETERS = {'task': 'task', 'priority': 0, 'weights': [1.0], 'inequality': False}

    @classmethod
    def port_specs(cls, params: dict[str, Any]) -> list[PortSpec]:
        task = params['task']
        return [
            table_port('output', 'input', 'Output', task),
            table_port('control', 'input', 'Control', task),
            PortSpec(name='rows', direction='output', msg_type=ConstraintRows, type='constraint_rows',
                     semantics=ROWS_SEMANTICS),
            PortSpec(name='state', direction='output', msg_type=TaskState, type='task_state',
                     semantics=f'TaskState({task})'),
        ]

    def validate_parameters(self, params: dict[str, Any]) -> str | None:
        if params['priority'] < 0 or not all(w > 0 for w in params['weights']):
            return 'priority must be >= 0 and weights > 0'
        return None

    def configure(self, params: dict[str, Any]) -> None:
        self.task, self.priority = params['task'], params['priority']
        self.weights = np.asarray(params['weights'], dtype=float)
        self.inequality = params['inequality']

    def update(self, t: float) -> None:
        output_msg, control_msg = self.inputs['output'].latest, self.inputs['control'].latest
        if output_msg is None or control_msg is None:
            return
        output, control = read_table(output_msg), read_table(control_msg)
        if control.rows != output.rows:
            return  # the controller has not seen these outputs yet
        m = len(output.rows)
        rows = ConstraintRows(task=self.task, priority=self.priority, inequality=self.inequality, rows=m,
                              joint_names=list(output.columns[1:]))
        rows.stamp = stamp(t)
        rows.jacobian = output.matrix().reshape(-1).tolist()
        rows.desired = control.column('desired').tolist()
        rows.lower = control.column('lower').tolist()
        rows.upper = control.column('upper').tolist()
        rows.weights = np.broadcast_to(self.weights, (m,)).tolist()
        self.outputs['rows'].write(rows)
        error = control.column('error')
        state = TaskState(task=self.task, output=output.column('value').tolist(),
                          setpoint=control.column('setpoint').tolist(), error=error.tolist(),
                          error_norm=float(np.linalg.norm(error)), active=True)
        state.stamp = stamp(t)
        self.outputs['state'].write(state)

"""ConstraintRowsEntity: what a Task hands to the Solver and to its observers (paper §4.2
"Task": "delivering a set of constraints to the optimization problem", Fig. 2).

It joins the Constraint Output's Jacobian J_y with the Constraint Controller's desired output
velocity (or bounds), the Task's row ``weights`` and ``priority`` into ``itasc_msgs/ConstraintRows``
(port ``rows``), and publishes what the Task sees, ``itasc_msgs/TaskState`` (output y, setpoint,
error and its norm; port ``state``) for Monitors, recordings and plots, both stamped as the output:
the configuration the rows describe, which the Solver matches across Tasks. Switched off, it writes
rows of none, stamped with when that happened, so that the Task leaves the Solver's problem at once,
in any process.
"""

from __future__ import annotations

import math

import numpy as np
from itasc_msgs.msg import ConstraintRows, TaskState
from pydantic import Field, field_validator

from itasc_core.communication.ports import PortSpec
from itasc_core.computation.functional_entity import FunctionalEntity
from itasc_core.computation.parameters import ParameterModel
from itasc_core.itasc.entities.messages import RowsSample, TaskStateSample
from itasc_core.itasc.entities.messages import ROWS_SEMANTICS

from .common import TaskName, task_port

__all__ = ['ConstraintRowsEntity']


class ConstraintRowsEntity(FunctionalEntity):
    """The Task's constraint rows on the program-wide joint velocities, and its state."""

    class Parameters(ParameterModel):
        task: TaskName = 'task'
        """The Task it belongs to."""
        priority: int = Field(default=0, ge=0, le=2**32 - 1)  # ConstraintRows.priority: uint32
        """Priority level of the Task's rows, 0 highest."""
        weights: list[float] = Field(default_factory=lambda: [1.0], min_length=1)
        """Weight of each row in its level: one value, or one per output (finite, > 0)."""
        inequality: bool = False
        """Whether the rows are bounds (an inequality Task)."""

        @field_validator('weights')
        @classmethod
        def _positive(cls, value: list[float]) -> list[float]:
            if not all(0 < w < math.inf for w in value):
                raise ValueError('weights must be finite and > 0')
            return value

    @classmethod
    def port_specs(cls, params: Parameters) -> list[PortSpec]:
        task = params.task
        return [
            task_port('output', 'input', 'Output', task),
            task_port('control', 'input', 'Control', task),
            PortSpec(name='rows', direction='output', msg_type=ConstraintRows, type='constraint_rows',
                     semantics=ROWS_SEMANTICS),
            PortSpec(name='state', direction='output', msg_type=TaskState, type='task_state',
                     semantics=f'TaskState({task})'),
        ]

    def configure(self, params: Parameters) -> None:
        output = self.inputs['output'].latest  # the rows it writes now (None before the first)
        if output is not None and len(params.weights) not in (1, len(output.names)):
            raise ValueError(f'weights has {len(params.weights)} values for the {len(output.names)} rows of '
                             f'task {params.task} ({", ".join(output.names)}): give one, or one per row')
        self.task, self.priority = params.task, params.priority
        self.weights = np.asarray(params.weights, dtype=float)
        self.inequality = params.inequality
        self._row_weights = self.weights  # one per row, remade when the number of rows changes

    def deactivate(self, t: float) -> None:
        last = self.outputs['rows'].last
        if last is None or last.rows == 0:
            return
        none = np.empty((0, len(last.joint_names)))
        self.outputs['rows'].write(RowsSample(
            max(t, last.t), self.task, priority=self.priority, inequality=self.inequality, joint_names=last.joint_names,
            jacobian=none, desired=np.empty(0), lower=np.empty(0), upper=np.empty(0), weights=np.empty(0)))

    def update(self, t: float) -> None:
        output, control = self.inputs['output'].latest, self.inputs['control'].latest
        if output is None or control is None:
            return
        if control.names != output.names:
            return  # the controller has not seen these outputs yet
        m = len(output.names)
        if self._row_weights.shape != (m,):
            self._row_weights = np.broadcast_to(self.weights, (m,)).copy()
        self.outputs['rows'].write(RowsSample(
            output.t, self.task, priority=self.priority, inequality=self.inequality, joint_names=output.joint_names,
            jacobian=output.jacobian, desired=control.desired, lower=control.lower, upper=control.upper,
            weights=self._row_weights))
        error = control.error
        self.outputs['state'].write(TaskStateSample(output.t, self.task, output=output.value, setpoint=control.setpoint,
                                                    error=error, error_norm=math.sqrt(float(error.dot(error)))))

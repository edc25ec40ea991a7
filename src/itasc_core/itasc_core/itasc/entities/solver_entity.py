"""SolverEntity: the Solver of a constraint-based program (paper §4.1 "Solver", §2.2).

Gathers the constraint rows of every Task (input ``rows``, one ``itasc_msgs/ConstraintRows``
sample per connected Task; only rows of the current tick count, so a Task the Coordinator
deactivated drops out at once), solves the prioritised problem with the configured solver
(``wdls``: weighted damped least squares with null-space priorities; ``qp``: cascade of QPs with
inequalities through qpsolvers) within the joint position and velocity limits, and writes

* ``command``: the joint velocity setpoints as ``sensor_msgs/JointState`` — ``name`` (the
  program's joints) and ``velocity``; a JointState rather than a bare array so that every
  Driver picks its own joints by name (semantics ``JointVelocities(program)``);
* ``status``: ``itasc_msgs/SolverStatus`` every tick.

It raises ``e_solver_singular`` / ``e_solver_saturated`` when the status becomes one of these
(and ``e_solver_ok`` when it recovers), and never outputs NaN or the answer to a problem it could
not solve: on any non-finite input or result, and on an infeasible problem (hard constraints that
contradict each other, a QP backend that fails), it commands zero velocity and raises
``e_emergency`` naming the reason, which puts the program in Safety.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from itasc_msgs.msg import ConstraintRows as RowsMsg
from itasc_msgs.msg import SolverStatus
from sensor_msgs.msg import JointState

from ...communication.ports import PortSpec
from ...computation.functional_entity import FunctionalEntity
from ..solver import ConstraintRows, QpSolver, WdlsSolver
from .messages import seconds, stamp
from .scene_entity import PROGRAM_JOINTS

__all__ = ['SolverEntity', 'PROGRAM_VELOCITIES', 'ROWS_SEMANTICS']

PROGRAM_VELOCITIES = 'JointVelocities(program)'
ROWS_SEMANTICS = f'ConstraintRows({PROGRAM_VELOCITIES})'


class NonFinite(ValueError):
    pass


class Infeasible(ValueError):
    pass


class SolverEntity(FunctionalEntity):
    """Joint velocities from the constraint rows of all active Tasks."""

    PARAMETERS = {
        'kind': 'wdls',            # wdls | qp
        'backend': 'daqp',         # qp: any qpsolvers backend
        'joint_names': [''],       # the program's joints (Scene order)
        'lower': [-math.inf],      # position limits per joint
        'upper': [math.inf],
        'velocity_limit': [math.inf],
        'joint_weights': [1.0],    # one value, or one per joint
        'damping': 0.1,            # wdls: maximum damping near singularities
        'regularization': 1e-6,    # qp: weight of the joint-velocity norm
        'position_limit_gain': 0.5,
        'period': 0.01,            # the nominal tick period, used until two ticks were seen
    }

    @classmethod
    def port_specs(cls, params: dict[str, Any]) -> list[PortSpec]:
        return [
            PortSpec(name='rows', direction='input', msg_type=RowsMsg, type='constraint_rows',
                     semantics=ROWS_SEMANTICS, multiple=True),
            PortSpec(name='joint_state', direction='input', msg_type=JointState, type='joint_state',
                     semantics=PROGRAM_JOINTS),
            PortSpec(name='command', direction='output', msg_type=JointState, type='joint_velocities',
                     semantics=PROGRAM_VELOCITIES),
            PortSpec(name='status', direction='output', msg_type=SolverStatus, type='solver_status',
                     semantics='SolverStatus(program)'),
        ]

    def validate_parameters(self, params: dict[str, Any]) -> str | None:
        if params['kind'] not in ('wdls', 'qp'):
            return f"kind must be 'wdls' or 'qp', got {params['kind']!r}"
        n = len([j for j in params['joint_names'] if j])
        for key in ('lower', 'upper', 'velocity_limit'):
            if len(params[key]) != n:
                return f'{key} has {len(params[key])} values for {n} joints'
        if len(params['joint_weights']) not in (1, n) or min(params['joint_weights']) <= 0:
            return 'joint_weights: one positive value, or one per joint'
        if params['damping'] < 0 or params['regularization'] <= 0 or params['period'] <= 0 \
                or not 0 < params['position_limit_gain'] <= 1:
            return 'damping >= 0, regularization > 0, 0 < position_limit_gain <= 1 and period > 0 expected'
        return None

    def configure(self, params: dict[str, Any]) -> None:
        self.joint_names = [j for j in params['joint_names'] if j]
        self._index = {name: i for i, name in enumerate(self.joint_names)}
        self.lower = np.array(params['lower'], dtype=float)
        self.upper = np.array(params['upper'], dtype=float)
        self.velocity_limit = np.array(params['velocity_limit'], dtype=float)
        weights = np.array(params['joint_weights'], dtype=float)
        common = {'joint_weights': weights[0] if weights.size == 1 else weights,
                  'position_limit_gain': params['position_limit_gain']}
        if params['kind'] == 'wdls':
            self.solver = WdlsSolver(max_damping=params['damping'], **common)
        else:
            self.solver = QpSolver(backend=params['backend'], regularization=params['regularization'], **common)
        self.period = params['period']
        self._last_t: float | None = None
        self._dt = self.period
        self.status = 'ok'

    # -- one step -------------------------------------------------------------------------------

    def update(self, t: float) -> None:
        if self._last_t is not None and t > self._last_t:
            self._dt = t - self._last_t
        self._last_t = t
        state = self.inputs['joint_state'].latest
        if state is None:
            self._command(np.zeros(len(self.joint_names)), t)
            return
        try:
            q = self._positions(state)
            rows = self._rows(t)
            result = self.solver.solve(rows, q=q, lower=self.lower, upper=self.upper,
                                       velocity_limit=self.velocity_limit, dt=self._dt)
            if not np.isfinite(result.qdot).all():
                raise NonFinite('the solver returned non-finite joint velocities')
            if result.infeasible:
                self._report(result, t)
                tasks = ', '.join(dict.fromkeys(result.violated)) or ', '.join(result.tasks)
                raise Infeasible(f'infeasible problem: the constraints of {tasks} cannot be met together')
        except (NonFinite, Infeasible) as err:
            self._command(np.zeros(len(self.joint_names)), t)
            self.raise_event('e_emergency', priority=True, detail=str(err))
            return
        self._command(result.qdot, t)
        self._report(result, t)

    def _positions(self, state: JointState) -> np.ndarray:
        by_name = dict(zip(state.name, state.position))
        q = np.array([by_name.get(n, math.nan) for n in self.joint_names], dtype=float)
        if not np.isfinite(q).all():
            raise NonFinite('joint positions missing or non-finite')
        return q

    def _rows(self, t: float) -> list[ConstraintRows]:
        """The rows of this tick (stale rows of deactivated Tasks are left out), in Scene order."""
        fresh = t - 1.5 * self._dt
        rows = []
        for msg in self.inputs['rows'].samples.values():
            if seconds(msg.stamp) < fresh or msg.rows == 0:
                continue
            J = np.zeros((msg.rows, len(self.joint_names)))
            columns = [self._index[name] for name in msg.joint_names]
            J[:, columns] = np.asarray(msg.jacobian, dtype=float).reshape(msg.rows, len(columns))
            row = ConstraintRows(msg.task, int(msg.priority), J, np.asarray(msg.desired, dtype=float),
                                 np.asarray(msg.lower, dtype=float), np.asarray(msg.upper, dtype=float),
                                 np.asarray(msg.weights, dtype=float), inequality=msg.inequality)
            if not (np.isfinite(J).all() and np.isfinite(row.desired).all() and np.isfinite(row.weights).all()
                    and not np.isnan(row.lower).any() and not np.isnan(row.upper).any()):
                raise NonFinite(f'non-finite constraint rows from task {msg.task}')
            rows.append(row)
        return rows

    def _command(self, qdot: np.ndarray, t: float) -> None:
        msg = JointState(name=self.joint_names, velocity=[float(v) for v in qdot])
        msg.header.stamp = stamp(t)
        self.outputs['command'].write(msg)

    def _report(self, result, t: float) -> None:
        if result.status != self.status:
            self.status = result.status
            self.raise_event(f'e_solver_{result.status}', detail=', '.join(result.tasks))
        sigma = float(result.min_singular_value)
        msg = SolverStatus(solver=self.entity_name, status=result.status, solve_time=result.solve_time,
                           min_singular_value=sigma if math.isfinite(sigma) else -1.0,  # -1: not computed
                           damping=float(result.damping),
                           active_tasks=list(result.tasks))
        msg.stamp = stamp(t)
        self.outputs['status'].write(msg)

    def disengage(self) -> None:
        self._command(np.zeros(len(self.joint_names)), self._last_t or 0.0)

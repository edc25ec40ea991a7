"""SolverEntity: the Solver of a constraint-based program (paper §4.1 "Solver", §2.2).

Gathers the constraint rows of every Task (input ``rows``, one ``itasc_msgs/ConstraintRows``
sample per connected Task, :class:`.messages.RowsSample`): the newest of each Task in this process
counts if it is of the current tick; that of a Task in another process (``--deploy per-composite``)
crosses DDS and comes a tick or more after the tick that triggered it, so it counts while it is at
most ``remote_rows_age`` old, unless this process switched its composite off. Rows are stamped with
the Scene tick whose configuration they describe, and rows from other processes arrive one by one,
each Task's at its own lag: the Solver then combines, of all contributing Tasks (in this process
too), the rows of the newest configuration each has rows of (it keeps each one's rows for
``remote_rows_age``, all that came between two of its ticks, :meth:`.InputPort.take_arrived`),
never the newest of each. Rows of two configurations are no longer quite in
each other's row space: a higher-priority inequality (an obstacle distance) that the configuration
leaves no redundancy for was met by a joint velocity hundreds of times the task's (a tick at a
joint's velocity limit, the next back, now and then in a per-composite run). With no configuration
in common, it solves again with the rows it last combined while those count, and with none after
(and says so in its log).
A Task the Coordinator deactivated writes rows of none and drops out at once. A Task in another
process whose rows stop coming (its process stalled, or died) does not drop out: once its newest
rows are older than ``remote_rows_age`` the Solver holds still until they come again (and says so
in its log, unless this process commanded that Task's composite to stop), since a problem without
them is not the program's: the constraint that vanished might be an obstacle's distance. A dead
process's composite is noticed by its parent, which goes to Safety (paper §6). It solves the
prioritised problem with the configured solver (a registered Solver kind, :mod:`..solver.kind`:
``wdls``, weighted damped least squares with null-space priorities; ``qp``, a cascade of QPs with
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
from collections.abc import Mapping
from typing import Any

import numpy as np
from itasc_msgs.msg import ConstraintRows as RowsMsg
from itasc_msgs.msg import SolverStatus
from pydantic import Field, model_validator
from sensor_msgs.msg import JointState

from ...communication.event_names import SAFETY_EVENT, solver_status
from ...communication.ports import PortSpec
from ...computation.functional_entity import FunctionalEntity
from ...computation.parameters import ParameterModel
from ...finite import all_finite
from ...kinds import with_kind
from ..solver.kind import SOLVERS
from ..solver.problem import ConstraintRows
from .messages import PROGRAM_VELOCITIES, ROWS_SEMANTICS, JointSample, RowsSample, SolverStatusSample
from .scene_entity import PROGRAM_JOINTS

__all__ = ['SolverEntity', 'SolverSettings']


class SolverSettings(ParameterModel):
    """How the Solver solves: a registered Solver kind (``wdls``: weighted damped least squares,
    priorities by null-space projection; ``qp``: a cascade of QPs with inequalities) and its settings."""

    kind: str = 'wdls'
    """The Solver: a registered solver kind (``wdls`` or ``qp``; its settings follow)."""
    position_limit_gain: float = Field(default=0.5, gt=0, le=1)
    """Fraction of the distance to a joint's position limit it may close in one second (0 < gain ≤ 1)."""


class NonFinite(ValueError):
    pass


class Infeasible(ValueError):
    pass


class SolverEntity(FunctionalEntity):
    """Joint velocities from the constraint rows of all active Tasks."""

    class Parameters(SolverSettings):
        joint_names: list[str] = Field(default_factory=list, frozen=True)
        """The program's joints (Scene order)."""
        lower: list[float] = Field(default_factory=list)
        """Lowest position per joint [rad or m]."""
        upper: list[float] = Field(default_factory=list)
        """Highest position per joint [rad or m]."""
        velocity_limit: list[float] = Field(default_factory=list)
        """Largest speed per joint [rad/s or m/s]."""
        joint_weights: list[float] = Field(default_factory=lambda: [1.0])
        """Weight of each joint's velocity: one value, or one per joint (> 0)."""
        period: float = Field(default=0.01, gt=0)
        """The nominal tick period [s], used until two ticks were seen."""
        remote_rows_age: float = Field(default=0.1, gt=0)
        """How old the rows of a Task in another process may be and still count [s]; older, the robot holds
        still until they come again."""

        @model_validator(mode='after')
        def _per_joint(self) -> 'SolverEntity.Parameters':
            n = len(self.joint_names)
            for key in ('lower', 'upper', 'velocity_limit'):
                if len(getattr(self, key)) != n:
                    raise ValueError(f'{key} has {len(getattr(self, key))} values for {n} joints')
            if len(self.joint_weights) not in (1, n) or min(self.joint_weights) <= 0:
                raise ValueError('joint_weights: one positive value, or one per joint')
            return self

    @classmethod
    def parameter_model(cls, values: Mapping[str, Any]) -> type[ParameterModel]:
        return with_kind(cls.Parameters, SOLVERS, field='kind', values=values)

    @classmethod
    def port_specs(cls, params: Any) -> list[PortSpec]:
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

    def configure(self, params: Any) -> None:
        self.joint_names = tuple(params.joint_names)
        self._index = {name: i for i, name in enumerate(self.joint_names)}
        self._columns: dict[tuple[str, ...], list[int]] = {}
        self.lower = np.array(params.lower, dtype=float)
        self.upper = np.array(params.upper, dtype=float)
        self.velocity_limit = np.array(params.velocity_limit, dtype=float)
        weights = np.array(params.joint_weights, dtype=float)
        joint_weights = weights[0] if weights.size == 1 else weights
        self.solver = SOLVERS[params.kind].create(params, joint_weights=joint_weights,
                                                  position_limit_gain=params.position_limit_gain)
        self.period = params.period
        self.remote_rows_age = params.remote_rows_age
        #: per topic of a contributing Task, with Tasks in other processes: its rows by stamp, as long as they count
        self._configurations: dict[str, dict[float, RowsSample]] = {}
        #: the stamp of the rows last combined, and those rows by topic
        self._combined: tuple[float, dict[str, RowsSample]] = (-math.inf, {})
        #: the Tasks in other processes whose rows were too old at the last tick (the robot held still)
        self._late: list[str] = []
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
            if not all_finite(result.qdot):
                raise NonFinite('the solver returned non-finite joint velocities')
            if result.infeasible:
                self._report(result, t)
                tasks = ', '.join(dict.fromkeys(result.violated)) or ', '.join(result.tasks)
                raise Infeasible(f'infeasible problem: the constraints of {tasks} cannot be met together')
        except (NonFinite, Infeasible) as err:
            self._command(np.zeros(len(self.joint_names)), t)
            self.raise_event(SAFETY_EVENT, priority=True, detail=str(err))
            return
        self._command(result.qdot, t)
        self._report(result, t)

    def _positions(self, state: JointSample) -> np.ndarray:
        if state.name == self.joint_names:  # the Scene's order
            q = state.position
        else:
            by_name = dict(zip(state.name, state.position))
            q = np.array([by_name.get(n, math.nan) for n in self.joint_names], dtype=float)
        if q.shape != (len(self.joint_names),) or not all_finite(q):
            raise NonFinite('joint positions missing or non-finite')
        return q

    def _rows(self, t: float) -> list[ConstraintRows]:
        """The rows that count in this tick (see the module's docstring), in Scene order."""
        port = self.inputs['rows']
        fresh, remote_fresh = t - 1.5 * self._dt, t - self.remote_rows_age
        counting = {topic: sample for topic, sample in port.samples.items()
                    if sample.t >= (remote_fresh if topic in port.remote else fresh) and not port.switched_off(topic)}
        if not port.remote:
            return [self._problem_rows(sample) for sample in counting.values() if sample.rows]
        late = [topic for topic, sample in port.samples.items()
                if sample.rows and topic in port.remote and topic not in counting and not port.switched_off(topic)]
        # a Task commanded to stop holds the robot still too, but that is the stop, not a fault to say
        unexpected = sorted(port.samples[topic].task for topic in late if not port.stopping(topic))
        if unexpected != self._late and unexpected:
            self.get_logger().warning(f'the rows of {", ".join(unexpected)} are older than remote_rows_age '
                                      f'({self.remote_rows_age:g} s): the robot holds still until they come')
        self._late = unexpected
        if late:
            self._combined = -math.inf, {}
            return []
        arrived = {topic: port.take_arrived(topic) for topic in port.remote}
        return [self._problem_rows(sample)
                for sample in self._one_configuration(counting, arrived=arrived, oldest=remote_fresh) if sample.rows]

    def _one_configuration(self, counting: dict[str, RowsSample], *, arrived: dict[str, list[RowsSample]],
                           oldest: float) -> list[RowsSample]:
        """Of the Tasks that contribute rows (``counting``: topic -> its newest rows; ``arrived``:
        topic -> all its rows that came since the last tick), the rows of the newest configuration
        (stamp, not before ``oldest``) that each has rows of; if they have none in common, the rows
        last combined while those count, else none."""
        history = self._configurations
        for topic in [topic for topic in history if topic not in counting or not counting[topic].rows]:
            del history[topic]  # gone, switched off, stale or writing rows of none
        contributing = [topic for topic, sample in counting.items() if sample.rows]
        for topic in contributing:
            stamps = history.setdefault(topic, {})
            for sample in (*arrived.get(topic, ()), counting[topic]):  # all that came since the last tick
                if sample.rows and sample.t >= oldest and sample.t > next(reversed(stamps), -math.inf):
                    stamps[sample.t] = sample
            while len(stamps) > 1 and next(iter(stamps)) < oldest:  # kept while they count (one process may lag)
                del stamps[next(iter(stamps))]
        first, *others = [history[topic] for topic in contributing] or [{}]
        stamp = max((s for s in first if all(s in other for other in others)), default=None)
        last_stamp, last = self._combined
        if stamp is not None:
            self._combined = stamp, {topic: history[topic][stamp] for topic in contributing}
        elif last_stamp < oldest:
            if last:
                tasks = ', '.join(sorted(counting[topic].task for topic in contributing))
                self.get_logger().warning(f'the rows of {tasks} share no configuration within remote_rows_age '
                                          f'({self.remote_rows_age:g} s): the robot holds still until they do',
                                          throttle_duration_sec=1.0)
            self._combined = -math.inf, {}
        else:
            self._combined = last_stamp, {topic: last[topic] for topic in contributing if topic in last}
        return list(self._combined[1].values())

    def _problem_rows(self, sample: RowsSample) -> ConstraintRows:
        J = sample.jacobian
        if sample.joint_names != self.joint_names:  # columns of some joints, in another order
            columns = self._columns.get(sample.joint_names)
            if columns is None:
                columns = self._columns[sample.joint_names] = [self._index[name] for name in sample.joint_names]
            J = np.zeros((sample.rows, len(self.joint_names)))
            J[:, columns] = sample.jacobian
        row = ConstraintRows(sample.task, int(sample.priority), J, sample.desired, sample.lower, sample.upper,
                             sample.weights, inequality=sample.inequality)
        # one sum each for the usual case (a NaN or inf makes it non-finite; Python's over the few
        # values of a Task's rows); the exact test otherwise
        if not (math.isfinite(J.sum()) and all_finite(row.desired) and all_finite(row.weights)
                and not math.isnan(sum(row.lower.tolist()) - sum(row.upper.tolist()))):
            if not (np.isfinite(J).all() and np.isfinite(row.desired).all() and np.isfinite(row.weights).all()
                    and not np.isnan(row.lower).any() and not np.isnan(row.upper).any()):
                raise NonFinite(f'non-finite constraint rows from task {sample.task}')
        return row

    def _command(self, qdot: np.ndarray, t: float) -> None:
        self.outputs['command'].write(JointSample(t, self.joint_names, velocity=qdot))

    def _report(self, result, t: float) -> None:
        if result.status != self.status:
            self.status = result.status
            self.raise_event(solver_status(result.status), detail=', '.join(result.tasks))
        sigma = float(result.min_singular_value)
        self.outputs['status'].write(SolverStatusSample(
            t, self.entity_name, status=result.status, solve_time=result.solve_time,
            min_singular_value=sigma if math.isfinite(sigma) else -1.0,  # -1: not computed
            damping=float(result.damping), active_tasks=tuple(result.tasks)))

    def disengage(self) -> None:
        self._command(np.zeros(len(self.joint_names)), self._last_t or 0.0)

"""Data-flow samples of the constraint-based program's Functional Entities (paper §4.1, §7).

Between the Scene, the entities of a Task and the Solver flow coordinates with their Jacobian, the
setpoints and what the controllers ask of the Solver, each as a typed message of ``itasc_msgs``
(names once, numbers as arrays) and, inside a process, as its sample
(:mod:`itasc_core.communication.samples`):

=====================  ===========================  ==============================================
sample                 message                      written by
=====================  ===========================  ==============================================
:class:`FeaturesSample`  ``itasc_msgs/Features``    Scene (``relation_<task>``), VKC, CO
:class:`SetpointSample`  ``itasc_msgs/Setpoint``    Setpoint Generator
:class:`ControlSample`   ``itasc_msgs/Control``     Constraint Controller
:class:`RowsSample`      ``itasc_msgs/ConstraintRows``  a Task's Rows, for the Solver
:class:`TaskStateSample` ``itasc_msgs/TaskState``   a Task's Rows, for Monitors and observers
:class:`SolverStatusSample` ``itasc_msgs/SolverStatus``  Solver
=====================  ===========================  ==============================================

``t`` is the program time of the Scheduler tick that produced the data. What a Task derives from the
Scene's configuration (features, output, rows, state) keeps the stamp of the Scene's tick it was
computed from, so that a Solver can tell this tick's rows from stale ones, and rows of one
configuration from those of another.
"""

from __future__ import annotations

import numpy as np
from itasc_msgs.msg import ConstraintRows, Control, Features, Setpoint, SolverStatus, TaskState

from ...communication.samples import JointSample, Sample, floats, sample_of, seconds, stamp
from ..coordinates import pose_coordinates, pose_features

__all__ = ['FeaturesSample', 'SetpointSample', 'ControlSample', 'RowsSample', 'TaskStateSample',
           'SolverStatusSample', 'JointSample', 'stamp', 'seconds', 'PROGRAM_VELOCITIES', 'ROWS_SEMANTICS']

#: What the Solver commands (its ``command`` output, the Drivers' input).
PROGRAM_VELOCITIES = 'JointVelocities(program)'
#: What every Task's Rows write and the Solver reads.
ROWS_SEMANTICS = f'ConstraintRows({PROGRAM_VELOCITIES})'


@sample_of(Features)
class FeaturesSample(Sample):
    """Coordinates ``value`` (one per name) and their ``jacobian`` (len(names) x len(joint_names))
    on the program-wide joint velocities; ``rotation``: first row of a log3 triple, or None.
    ``pose``: a relation's pose as ``pin.SE3``, handed on in the process (not in the message: a
    reader of the message takes it from ``value``).

    A relation's sample may be written with its ``pose`` and no ``value``: the coordinates are
    then those of the pose (:func:`~itasc_core.itasc.coordinates.pose_features`, ``xyz_log3``
    where ``rotation`` marks the triple), computed when first read. In a process, the VKC reads the
    pose and computes the coordinates its chain needs (a distance needs no log3); only a reader of
    the message (DDS, the recorder) or of ``value`` costs the conversion (issue #9: 2 x 6 us a tick
    in ``approach_object``)."""

    __slots__ = ('t', 'names', 'joint_names', '_value', 'jacobian', 'rotation', 'pose')
    MESSAGE_FIELDS = {'rotation': lambda s: -1 if s.rotation is None else s.rotation}

    def __init__(self, t: float, names: tuple[str, ...], joint_names: tuple[str, ...], value: np.ndarray | None,
                 jacobian: np.ndarray, rotation: int | None = None, *, pose=None) -> None:
        if value is None and pose is None:
            raise ValueError('features need their value or the pose it is the coordinates of')
        self.t, self.names, self.joint_names = t, names, joint_names
        self._value, self.jacobian, self.rotation, self.pose = value, jacobian, rotation, pose

    @property
    def value(self) -> np.ndarray:
        if self._value is None:  # a sample is not changed: this is the value it was written with
            self._value = pose_features(self.pose, coordinates=pose_coordinates(self.rotation))
        return self._value

    def to_message(self) -> Features:
        msg = Features(names=list(self.names), joint_names=list(self.joint_names),
                       rotation=-1 if self.rotation is None else self.rotation,
                       value=self.value.tolist(), jacobian=self.jacobian.reshape(-1).tolist())
        msg.stamp = stamp(self.t)
        return msg

    @classmethod
    def from_message(cls, msg: Features) -> 'FeaturesSample':
        names, joints = tuple(msg.names), tuple(msg.joint_names)
        jacobian = floats(msg.jacobian)
        if len(msg.value) != len(names) or jacobian.size != len(names) * len(joints):
            raise ValueError(f'features of {len(names)} names on {len(joints)} joints carry {len(msg.value)} '
                             f'values and {jacobian.size} Jacobian entries')
        return cls(seconds(msg.stamp), names, joints, floats(msg.value), jacobian.reshape(len(names), len(joints)),
                   None if msg.rotation < 0 else msg.rotation)


@sample_of(Setpoint)
class SetpointSample(Sample):
    """The desired ``value`` of each output (``names``) and its ``velocity`` (feed-forward)."""

    __slots__ = ('t', 'names', 'value', 'velocity')

    def __init__(self, t: float, names: tuple[str, ...], value: np.ndarray, velocity: np.ndarray) -> None:
        self.t, self.names, self.value, self.velocity = t, names, value, velocity

    def to_message(self) -> Setpoint:
        msg = Setpoint(names=list(self.names), value=self.value.tolist(), velocity=self.velocity.tolist())
        msg.stamp = stamp(self.t)
        return msg

    @classmethod
    def from_message(cls, msg: Setpoint) -> 'SetpointSample':
        return cls(seconds(msg.stamp), tuple(msg.names), floats(msg.value), floats(msg.velocity))


@sample_of(Control)
class ControlSample(Sample):
    """Per output (``names``): ``desired`` velocity, ``lower``/``upper`` bounds on it, the
    ``setpoint`` controlled to and the ``error``."""

    __slots__ = ('t', 'names', 'desired', 'lower', 'upper', 'setpoint', 'error')

    def __init__(self, t: float, names: tuple[str, ...], *, desired: np.ndarray, lower: np.ndarray,
                 upper: np.ndarray, setpoint: np.ndarray, error: np.ndarray) -> None:
        self.t, self.names = t, names
        self.desired, self.lower, self.upper, self.setpoint, self.error = desired, lower, upper, setpoint, error

    def to_message(self) -> Control:
        msg = Control(names=list(self.names), desired=self.desired.tolist(), lower=self.lower.tolist(),
                      upper=self.upper.tolist(), setpoint=self.setpoint.tolist(), error=self.error.tolist())
        msg.stamp = stamp(self.t)
        return msg

    @classmethod
    def from_message(cls, msg: Control) -> 'ControlSample':
        return cls(seconds(msg.stamp), tuple(msg.names), desired=floats(msg.desired), lower=floats(msg.lower),
                   upper=floats(msg.upper), setpoint=floats(msg.setpoint), error=floats(msg.error))


@sample_of(ConstraintRows)
class RowsSample(Sample):
    """A Task's constraint rows: ``jacobian`` (rows x len(joint_names)), ``desired``, ``lower``,
    ``upper``, ``weights`` per row, at a ``priority`` level (0 highest)."""

    __slots__ = ('t', 'task', 'priority', 'inequality', 'joint_names', 'jacobian', 'desired', 'lower', 'upper',
                 'weights')

    def __init__(self, t: float, task: str, *, priority: int, inequality: bool, joint_names: tuple[str, ...],
                 jacobian: np.ndarray, desired: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                 weights: np.ndarray) -> None:
        self.t, self.task, self.priority, self.inequality = t, task, priority, inequality
        self.joint_names, self.jacobian = joint_names, jacobian
        self.desired, self.lower, self.upper, self.weights = desired, lower, upper, weights

    @property
    def rows(self) -> int:
        return self.jacobian.shape[0]

    def to_message(self) -> ConstraintRows:
        msg = ConstraintRows(task=self.task, priority=self.priority, inequality=self.inequality, rows=self.rows,
                             joint_names=list(self.joint_names), jacobian=self.jacobian.reshape(-1).tolist(),
                             desired=self.desired.tolist(), lower=self.lower.tolist(), upper=self.upper.tolist(),
                             weights=self.weights.tolist())
        msg.stamp = stamp(self.t)
        return msg

    @classmethod
    def from_message(cls, msg: ConstraintRows) -> 'RowsSample':
        jacobian = floats(msg.jacobian)
        if jacobian.size != msg.rows * len(msg.joint_names):
            raise ValueError(f'{msg.rows} rows on {len(msg.joint_names)} joints carry {jacobian.size} Jacobian entries')
        return cls(seconds(msg.stamp), msg.task, priority=msg.priority, inequality=msg.inequality,
                   joint_names=tuple(msg.joint_names), jacobian=jacobian.reshape(msg.rows, len(msg.joint_names)),
                   desired=floats(msg.desired), lower=floats(msg.lower), upper=floats(msg.upper),
                   weights=floats(msg.weights))


@sample_of(TaskState)
class TaskStateSample(Sample):
    """What a Task sees: its ``output`` y, ``setpoint``, ``error`` and ``error_norm``."""

    __slots__ = ('t', 'task', 'output', 'setpoint', 'error', 'error_norm', 'active')

    def __init__(self, t: float, task: str, *, output: np.ndarray, setpoint: np.ndarray, error: np.ndarray,
                 error_norm: float, active: bool = True) -> None:
        self.t, self.task, self.output, self.setpoint, self.error = t, task, output, setpoint, error
        self.error_norm, self.active = error_norm, active

    def to_message(self) -> TaskState:
        msg = TaskState(task=self.task, output=self.output.tolist(), setpoint=self.setpoint.tolist(),
                        error=self.error.tolist(), error_norm=self.error_norm, active=self.active)
        msg.stamp = stamp(self.t)
        return msg

    @classmethod
    def from_message(cls, msg: TaskState) -> 'TaskStateSample':
        return cls(seconds(msg.stamp), msg.task, output=floats(msg.output), setpoint=floats(msg.setpoint),
                   error=floats(msg.error), error_norm=msg.error_norm, active=msg.active)


@sample_of(SolverStatus)
class SolverStatusSample(Sample):
    """One Solver step: ``status``, ``solve_time`` [s], ``min_singular_value`` (-1: not
    computed), ``damping`` and the ``active_tasks``."""

    __slots__ = ('t', 'solver', 'status', 'solve_time', 'min_singular_value', 'damping', 'active_tasks')

    def __init__(self, t: float, solver: str, *, status: str, solve_time: float, min_singular_value: float,
                 damping: float, active_tasks: tuple[str, ...]) -> None:
        self.t, self.solver, self.status, self.solve_time = t, solver, status, solve_time
        self.min_singular_value, self.damping, self.active_tasks = min_singular_value, damping, active_tasks

    def to_message(self) -> SolverStatus:
        msg = SolverStatus(solver=self.solver, status=self.status, solve_time=self.solve_time,
                           min_singular_value=self.min_singular_value, damping=self.damping,
                           active_tasks=list(self.active_tasks))
        msg.stamp = stamp(self.t)
        return msg

    @classmethod
    def from_message(cls, msg: SolverStatus) -> 'SolverStatusSample':
        return cls(seconds(msg.stamp), msg.solver, status=msg.status, solve_time=msg.solve_time,
                   min_singular_value=msg.min_singular_value, damping=msg.damping,
                   active_tasks=tuple(msg.active_tasks))

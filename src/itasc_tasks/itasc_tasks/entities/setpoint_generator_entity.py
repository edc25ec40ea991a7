"""SetpointGeneratorEntity: the Setpoint Generator of a Task (paper §4.1, §4.2, Fig. 2).

Wraps :mod:`itasc_tasks.setpoint_generator`. ``kind``:

* ``hold``: hold the output where it was when the Task became active;
* ``fixed``: a constant ``target``;
* ``minimum_jerk`` / ``trapezoidal``: a smooth point-to-point motion from the current output to
  ``target`` (``duration``, ``max_velocity``, ``max_acceleration``);
* ``periodic``: ``offset + amplitude sin(2 pi t / period + phase)``;
* ``topic``: values (in output space) received on the ROS topic ``topic``
  (``std_msgs/Float64MultiArray``); holds the current output until the first one arrives; a
  value that is not finite or not one per output raises ``e_emergency`` (Safety).

``target`` is in output space, or, with ``target_is_pose``, the pose ``[x, y, z, roll, pitch,
yaw]`` of o2 in o1 (a Cartesian Task; interpolated along the geodesic). A point-to-point motion
restarts from the current output whenever the Task is (re)activated or the parameters change
(a configuration may switch the target). Input ``features`` (``Features(<task>)``) gives the
current value; outputs ``setpoint`` (labelled table: columns ``value`` and ``velocity``, the
feed-forward) and ``progress`` (``std_msgs/Float64``: share of the motion done, 1 when the target
is reached; Monitors watch it to tell the Coordinator that a motion is over).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin
from std_msgs.msg import Float64, Float64MultiArray

from itasc_core.communication.ports import PortSpec
from itasc_core.computation.functional_entity import FunctionalEntity
from itasc_core.communication.qos import DATA_QOS
from itasc_core.itasc.entities.messages import Table, read_table, table_msg
from itasc_core.itasc.robot import se3

from ..setpoint_generator import (FixedSetpoint, MinimumJerkSetpoint, PeriodicSetpoint, TopicSetpoint,
                                  TrapezoidalSetpoint)
from .common import Ticks, names, table_port

__all__ = ['SetpointGeneratorEntity']

KINDS = ('hold', 'fixed', 'minimum_jerk', 'trapezoidal', 'periodic', 'topic')
_POINT_TO_POINT = (MinimumJerkSetpoint, TrapezoidalSetpoint)


class SetpointGeneratorEntity(FunctionalEntity):
    """Desired values y_d (and their velocity) for the Task's controller."""

    PARAMETERS = {
        'task': 'task',
        'tick_period': 0.01,      # the program's nominal tick period [s]
        'kind': 'hold',
        'outputs': [''],            # the Task's outputs, as the Constraint Output selects them
        'target': [0.0],
        'target_is_pose': False,
        'duration': 0.0,
        'max_velocity': [0.0],      # 0: unbounded
        'max_acceleration': [1.0],
        'amplitude': [0.0],
        'period': 1.0,
        'offset': [0.0],
        'phase': [0.0],
        'topic': '',
    }

    @classmethod
    def port_specs(cls, params: dict[str, Any]) -> list[PortSpec]:
        return [
            table_port('features', 'input', 'Features', params['task']),
            table_port('setpoint', 'output', 'Setpoint', params['task']),
            PortSpec(name='progress', direction='output', msg_type=Float64, type='progress',
                     semantics=f"Progress({params['task']})"),
        ]

    def validate_parameters(self, params: dict[str, Any]) -> str | None:
        if params['kind'] not in KINDS:
            return f"kind must be one of {KINDS}, got {params['kind']!r}"
        if params['target_is_pose'] and len(params['target']) != 6:
            return 'a pose target is [x, y, z, roll, pitch, yaw]'
        if params['duration'] < 0 or params['period'] <= 0:
            return 'duration >= 0 and period > 0 expected'
        if params['kind'] == 'topic' and not params['topic']:
            return "kind 'topic' needs a topic"
        return None

    def configure(self, params: dict[str, Any]) -> None:
        self.outputs_selected = names(params['outputs'])
        self.kind = params['kind']
        target: Any = np.array(params['target'], dtype=float)
        if params['target_is_pose']:
            target = se3(target[:3], target[3:])
        max_velocity = [v if v > 0 else np.inf for v in params['max_velocity']]
        max_velocity = None if all(np.isinf(max_velocity)) else max_velocity
        self.generator = {
            'hold': lambda: None,
            'fixed': lambda: FixedSetpoint(target),
            'minimum_jerk': lambda: MinimumJerkSetpoint(target, duration=params['duration'],
                                                        max_velocity=max_velocity),
            'trapezoidal': lambda: TrapezoidalSetpoint(
                target, duration=params['duration'], max_velocity=max_velocity or np.inf,
                max_acceleration=params['max_acceleration']),
            'periodic': lambda: PeriodicSetpoint(amplitude=params['amplitude'], period=params['period'],
                                                 offset=params['offset'], phase=params['phase']),
            'topic': lambda: TopicSetpoint(),
        }[self.kind]()
        self._subscribe(params['topic'] if self.kind == 'topic' else '')
        self._ticks = getattr(self, '_ticks', None) or Ticks(params['tick_period'])
        self._ticks.period = params['tick_period']
        self._restart = True
        self._t0 = 0.0

    def _subscribe(self, topic: str) -> None:
        current = getattr(self, '_subscription', None)
        if current is not None and current.topic_name != topic:
            self.destroy_subscription(current)
            current = None
        if topic and current is None:
            current = self.create_subscription(Float64MultiArray, topic, self._on_value, DATA_QOS)
        self._subscription = current

    def _on_value(self, msg: Float64MultiArray) -> None:
        if isinstance(self.generator, TopicSetpoint):
            self.generator.push(np.asarray(msg.data, dtype=float))

    def start(self) -> None:
        """Starting (also again, after a recovery from Safety): the next tick starts the setpoint
        from where the Task is then."""
        self._ticks.reset()

    def activate(self) -> None:
        self._ticks.restart()

    def update(self, t: float) -> None:
        msg = self.inputs['features'].latest
        if msg is None:
            return
        table = read_table(msg)
        index = [table.rows.index(n) for n in self.outputs_selected] if self.outputs_selected \
            else list(range(len(table.rows)))
        _, resumed = self._ticks.step(t)
        if resumed or self._restart:
            self._start(table, index, t)
        value, velocity = self.generator(t)
        if isinstance(value, pin.SE3):
            value = _features_of(value, table)[index]
            velocity = np.asarray(velocity)[index]
        if self.kind == 'topic' and (np.shape(value) != (len(index),) or not np.isfinite(value).all()):
            self.raise_event('e_emergency', priority=True,
                             detail=f"{self.params['topic']}: setpoint {np.asarray(value).tolist()} is not "
                                    f"{len(index)} finite values")
            return
        rows = [table.rows[i] for i in index]
        self.outputs['setpoint'].write(table_msg(rows, ('value', 'velocity'), np.column_stack([value, velocity])))
        self.outputs['progress'].write(Float64(data=self._progress(t)))

    def _start(self, table: Table, index: list[int], t: float) -> None:
        self._restart, self._t0 = False, t
        current = table.column('value')
        if self.kind == 'hold':
            self.generator = FixedSetpoint(current[index])
        elif isinstance(self.generator, _POINT_TO_POINT):
            pose_target = isinstance(self.generator.target, pin.SE3)
            self.generator.start(_pose_of(current, table) if pose_target else current[index], t)
        elif isinstance(self.generator, TopicSetpoint) and not self.generator.started:
            self.generator.start(current[index], t)

    def _progress(self, t: float) -> float:
        period = getattr(self.generator, 'period', 0.0) if isinstance(self.generator, _POINT_TO_POINT) else 0.0
        return 1.0 if period <= 0.0 else float(min(max((t - self._t0) / period, 0.0), 1.0))


def _features_of(pose: pin.SE3, table: Table) -> np.ndarray:
    """Feature coordinates of a relative pose, in the coordinates of the features table."""
    if table.rotation is not None:
        return np.concatenate([pose.translation, pin.log3(pose.rotation)])
    return pin.log6(pose).vector


def _pose_of(features: np.ndarray, table: Table) -> pin.SE3:
    if table.rotation is not None:
        return pin.SE3(pin.exp3(features[3:6]), features[0:3].copy())
    return pin.exp6(pin.Motion(features[:6]))

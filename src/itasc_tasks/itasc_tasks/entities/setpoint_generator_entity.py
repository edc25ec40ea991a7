"""SetpointGeneratorEntity: the Setpoint Generator of a Task (paper §4.1, §4.2, Fig. 2).

Runs the generator its ``kind`` makes, a registered setpoint generator (:mod:`itasc_tasks.setpoints`;
the generators are :mod:`itasc_tasks.setpoint_generator`'s). Its parameters are a Task's
``setpoint`` section (the same model) and the Task's outputs. The shipped kinds:

* ``hold``: hold the output where it was when the Task became active;
* ``fixed``: a constant target (``value`` or ``pose``);
* ``minimum_jerk`` / ``trapezoidal``: a smooth point-to-point motion from the current output to
  the target (``duration``, ``max_velocity``, ``max_acceleration``);
* ``periodic``: ``offset + amplitude sin(2 pi t / period + phase)``;
* ``topic``: values (in output space) received on the ROS topic ``topic``
  (``std_msgs/Float64MultiArray``); holds the current output until the first one arrives.

A setpoint that is not finite (of any kind), or a topic's that is not one value per output, raises
``e_emergency`` (Safety).

The target is ``value`` in output space, or ``pose``, the pose of o2 in o1 (a Cartesian Task;
interpolated along the geodesic). A point-to-point motion
restarts from the current output whenever the Task is (re)activated or the parameters change
(a configuration may switch the target). Input ``features`` (``Features(<task>)``) gives the
current value; outputs ``setpoint`` (``itasc_msgs/Setpoint``: ``value`` and ``velocity``, the
feed-forward, per output) and ``progress`` (``std_msgs/Float64``: share of the motion done, 1 when the target
is reached; Monitors watch it to tell the Coordinator that a motion is over).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from pydantic import Field
from rclpy.subscription import Subscription
from std_msgs.msg import Float64, Float64MultiArray

from itasc_core.communication.event_names import SAFETY_EVENT
from itasc_core.communication.ports import PortSpec
from itasc_core.computation.functional_entity import FunctionalEntity
from itasc_core.computation.parameters import Names, ParameterModel
from itasc_core.communication.qos import OUTSIDE_QOS
from itasc_core.communication.samples import Float64Sample
from itasc_core.finite import all_finite
from itasc_core.itasc.entities.messages import FeaturesSample, SetpointSample
from itasc_core.kinds import with_kind

from ..constraint_output import ConstraintOutput, Selection
from ..setpoint_generator import OutputSetpoint, PointToPoint, TopicSetpoint, start_value
from ..setpoints import SETPOINTS
from .common import TaskName, Ticks, task_port

__all__ = ['SetpointGeneratorEntity', 'SetpointBase']


class SetpointBase(ParameterModel):
    """A Setpoint Generator (paper §4.1): a registered kind and its fields. ``value`` is in output
    space; a Cartesian Task may give a ``pose`` of o2 in o1 instead."""

    kind: str
    """How the setpoint moves, a registered setpoint generator: ``hold`` where the Task found it,
    ``fixed``, ``minimum_jerk`` or ``trapezoidal`` towards ``value``/``pose``, ``periodic`` (a sine),
    or read from a ``topic``; its fields follow."""


class SetpointGeneratorEntity(FunctionalEntity):
    """Desired values y_d (and their velocity) for the Task's controller."""

    class Parameters(SetpointBase):
        kind: str = 'hold'
        """How the setpoint moves, a registered setpoint generator (its fields follow)."""
        task: TaskName = 'task'
        """The Task it belongs to."""
        tick_period: float = Field(default=0.01, gt=0)
        """The program's nominal tick period [s]."""
        outputs: Names = Field(default_factory=list, frozen=True)
        """The Task's outputs, as its Constraint Output selects them (none: all features)."""

    @classmethod
    def parameter_model(cls, values: Mapping[str, Any]) -> type[ParameterModel]:
        return with_kind(cls.Parameters, SETPOINTS, field='kind', values=values)

    @classmethod
    def port_specs(cls, params: Any) -> list[PortSpec]:
        return [
            task_port('features', 'input', 'Features', params.task),
            task_port('setpoint', 'output', 'Setpoint', params.task),
            PortSpec(name='progress', direction='output', msg_type=Float64, type='progress',
                     semantics=f'Progress({params.task})'),
        ]

    def configure(self, params: Any) -> None:
        self.co = ConstraintOutput(list(params.outputs) or None)
        self._output_setpoint = OutputSetpoint()
        kind = SETPOINTS[params.kind]
        self.generator = kind.generator(params)
        self.source = kind.topic(params)
        self._subscribe(self.source)
        self.source = self.source or f'setpoint {params.kind}'
        self._ticks = getattr(self, '_ticks', None) or Ticks(params.tick_period)
        self._ticks.period = params.tick_period
        self._restart = True
        self._t0 = 0.0

    def _subscribe(self, topic: str) -> None:
        current: Subscription | None = getattr(self, '_subscription', None)
        new = self.subscription_for(current, Float64MultiArray, topic, self._on_value, OUTSIDE_QOS) if topic else None
        self.let_go(current, kept=new)
        self._subscription = new

    def _on_value(self, msg: Float64MultiArray) -> None:
        self.generator.push(np.asarray(msg.data, dtype=float))  # type: ignore[attr-defined]  # a topic's kind

    def start(self) -> None:
        """Starting (also again, after a recovery from Safety): the next tick starts the setpoint
        from where the Task is then."""
        self._ticks.reset()

    def activate(self) -> None:
        self._ticks.restart()

    def update(self, t: float) -> None:
        features = self.inputs['features'].latest
        if features is None:
            return
        selection = self.co.bind(features.names, features.rotation)
        _, resumed = self._ticks.step(t)
        if resumed or self._restart:
            self._start(features, selection, t)
        value, velocity = self.generator(t)
        value, velocity = self._output_setpoint(value, velocity, selection=selection, rotation=features.rotation)
        names = selection.names
        value, velocity = np.asarray(value, dtype=float), np.asarray(velocity, dtype=float)
        if not all_finite(value) or (self._subscription is not None and value.shape != (len(names),)):
            self.raise_event(SAFETY_EVENT, priority=True,
                             detail=f'{self.source}: setpoint {value.tolist()} is not {len(names)} finite values')
            return
        if velocity.shape != value.shape:
            velocity = np.full(value.shape, velocity)
        self.outputs['setpoint'].write(SetpointSample(t, names, value, velocity))
        self.outputs['progress'].write(Float64Sample(self._progress(t)))

    def _start(self, features: FeaturesSample, selection: Selection, t: float) -> None:
        """Start the generator from where the Task is (a topic's only until its first value)."""
        self._restart, self._t0 = False, t
        if isinstance(self.generator, TopicSetpoint) and self.generator.started:
            return
        self.generator.start(start_value(self.generator, features=features.value,
                                         output=selection.select(features.value), rotation=features.rotation), t)

    def _progress(self, t: float) -> float:
        period = self.generator.period if isinstance(self.generator, PointToPoint) else 0.0
        return 1.0 if period <= 0.0 else float(min(max((t - self._t0) / period, 0.0), 1.0))

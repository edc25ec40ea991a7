"""SetpointGeneratorEntity: the Setpoint Generator of a Task (paper §4.1, §4.2, Fig. 2).

Calls :mod:`itasc_tasks.setpoint_generator`. Its parameters are a Task's ``setpoint`` section
(:class:`Setpoint`, the same model) and the Task's outputs. ``kind``:

* ``hold``: hold the output where it was when the Task became active;
* ``fixed``: a constant target (``value`` or ``pose``);
* ``minimum_jerk`` / ``trapezoidal``: a smooth point-to-point motion from the current output to
  the target (``duration``, ``max_velocity``, ``max_acceleration``);
* ``periodic``: ``offset + amplitude sin(2 pi t / period + phase)``;
* ``topic``: values (in output space) received on the ROS topic ``topic``
  (``std_msgs/Float64MultiArray``); holds the current output until the first one arrives; a
  value that is not finite or not one per output raises ``e_emergency`` (Safety).

The target is ``value`` in output space, or ``pose``, the pose of o2 in o1 (a Cartesian Task;
interpolated along the geodesic). A point-to-point motion
restarts from the current output whenever the Task is (re)activated or the parameters change
(a configuration may switch the target). Input ``features`` (``Features(<task>)``) gives the
current value; outputs ``setpoint`` (``itasc_msgs/Setpoint``: ``value`` and ``velocity``, the
feed-forward, per output) and ``progress`` (``std_msgs/Float64``: share of the motion done, 1 when the target
is reached; Monitors watch it to tell the Coordinator that a motion is over).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Literal

import numpy as np
from pydantic import Field, field_validator, model_validator
from std_msgs.msg import Float64, Float64MultiArray

from itasc_core.communication.event_names import SAFETY_EVENT
from itasc_core.communication.ports import PortSpec
from itasc_core.computation.functional_entity import FunctionalEntity
from itasc_core.computation.parameters import ParameterModel
from itasc_core.communication.qos import DATA_QOS
from itasc_core.communication.samples import Float64Sample
from itasc_core.itasc.entities.messages import FeaturesSample, SetpointSample
from itasc_core.itasc.entities.scene_entity import Placement
from itasc_core.itasc.robot import se3

from ..constraint_output import ConstraintOutput, Selection
from ..setpoint_generator import (FixedSetpoint, HoldSetpoint, MinimumJerkSetpoint, OutputSetpoint,
                                  PeriodicSetpoint, PointToPoint, SetpointGenerator, TopicSetpoint,
                                  TrapezoidalSetpoint, start_value)
from .common import Ticks, task_port

__all__ = ['SetpointGeneratorEntity', 'Setpoint']


def _as_list(value: Any) -> Any:
    """Accept a scalar where a list is expected (``value: 0.3``)."""
    return [value] if isinstance(value, (int, float)) and not isinstance(value, bool) else value


class Setpoint(ParameterModel):
    """A Setpoint Generator (paper §4.1). ``value`` is in output space; a Cartesian Task may give a
    ``pose`` of o2 in o1 instead. ``hold`` keeps the output where the Task found it."""

    kind: Literal['hold', 'fixed', 'minimum_jerk', 'trapezoidal', 'periodic', 'topic']
    """How the setpoint moves: ``hold`` where the Task found it, ``fixed``, ``minimum_jerk`` or
    ``trapezoidal`` towards ``value``/``pose``, ``periodic`` (a sine), or read from a ``topic``."""
    value: list[float] | None = None
    """The target in output space, one number per output [m, rad or the output's unit]."""
    pose: Placement | None = None
    """A Cartesian Task's target: the pose of o2 in o1."""
    duration: float = Field(default=0.0, ge=0)
    """Time to reach the target [s] (``minimum_jerk``; 0: at once)."""
    max_velocity: list[float] | None = None
    """Per output [unit/s] (``trapezoidal``)."""
    max_acceleration: list[float] | None = None
    """Per output [unit/s²] (``trapezoidal``)."""
    amplitude: list[float] | None = None
    """Per output (``periodic``)."""
    period: float | None = Field(default=None, gt=0)
    """Period [s] (``periodic``)."""
    offset: list[float] | None = None
    """Centre per output (``periodic``; omitted: 0)."""
    phase: list[float] | None = None
    """Phase per output [rad] (``periodic``)."""
    topic: str | None = None
    """Topic of ``std_msgs/Float64MultiArray`` setpoints, one value per output (``topic``)."""

    _list = field_validator('value', 'max_velocity', 'max_acceleration', 'amplitude', 'offset', 'phase',
                            mode='before')(_as_list)

    @field_validator('max_velocity', 'max_acceleration')
    @classmethod
    def _positive(cls, value: list[float] | None) -> list[float] | None:
        if value is not None and any(v <= 0 for v in value):
            raise ValueError('must be > 0')
        return value

    @model_validator(mode='after')
    def _complete(self) -> 'Setpoint':
        if self.kind in ('fixed', 'minimum_jerk', 'trapezoidal') and (self.value is None) == (self.pose is None):
            raise ValueError(f"setpoint '{self.kind}' needs exactly one of value or pose")
        if self.kind == 'periodic' and (self.amplitude is None or self.period is None):
            raise ValueError("setpoint 'periodic' needs amplitude and period")
        if self.kind == 'topic' and not self.topic:
            raise ValueError("setpoint 'topic' needs a topic")
        return self


class SetpointGeneratorEntity(FunctionalEntity):
    """Desired values y_d (and their velocity) for the Task's controller."""

    class Parameters(Setpoint):
        kind: Literal['hold', 'fixed', 'minimum_jerk', 'trapezoidal', 'periodic', 'topic'] = 'hold'
        """How the setpoint moves (see :class:`Setpoint`)."""
        task: str = 'task'
        """The Task it belongs to."""
        tick_period: float = Field(default=0.01, gt=0)
        """The program's nominal tick period [s]."""
        outputs: list[str] = Field(default_factory=list)
        """The Task's outputs, as its Constraint Output selects them (none: all features)."""

    @classmethod
    def port_specs(cls, params: Parameters) -> list[PortSpec]:
        return [
            task_port('features', 'input', 'Features', params.task),
            task_port('setpoint', 'output', 'Setpoint', params.task),
            PortSpec(name='progress', direction='output', msg_type=Float64, type='progress',
                     semantics=f'Progress({params.task})'),
        ]

    def configure(self, params: Parameters) -> None:
        self.co = ConstraintOutput(list(params.outputs) or None)
        self._output_setpoint = OutputSetpoint()
        self.kind = params.kind
        target: Any = se3(params.pose.xyz, params.pose.rpy) if params.pose is not None \
            else np.array(params.value or [0.0], dtype=float)
        max_velocity = params.max_velocity
        self.topic = params.topic or ''
        generators: dict[str, Callable[[], SetpointGenerator]] = {
            'hold': HoldSetpoint,
            'fixed': lambda: FixedSetpoint(target),
            'minimum_jerk': lambda: MinimumJerkSetpoint(target, duration=params.duration,
                                                        max_velocity=max_velocity),
            'trapezoidal': lambda: TrapezoidalSetpoint(
                target, duration=params.duration, max_velocity=max_velocity or np.inf,
                max_acceleration=params.max_acceleration or 1.0),
            'periodic': lambda: PeriodicSetpoint(amplitude=params.amplitude or 0.0, period=params.period or 1.0,
                                                 offset=params.offset or 0.0, phase=params.phase or 0.0),
            'topic': TopicSetpoint,
        }
        self.generator = generators[self.kind]()
        self._subscribe(self.topic if self.kind == 'topic' else '')
        self._ticks = getattr(self, '_ticks', None) or Ticks(params.tick_period)
        self._ticks.period = params.tick_period
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
        if self.kind == 'topic' and (np.shape(value) != (len(names),) or not np.isfinite(value).all()):
            self.raise_event(SAFETY_EVENT, priority=True,
                             detail=f"{self.topic}: setpoint {np.asarray(value).tolist()} is not "
                                    f"{len(names)} finite values")
            return
        value, velocity = np.asarray(value, dtype=float), np.asarray(velocity, dtype=float)
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

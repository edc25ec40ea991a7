"""The iTaSC application model (paper §4.2, Fig. 2): the three levels of composition written as a
small YAML DSL, validated with pydantic (unknown fields refused).

* **Application** — a Constraint-based program and the hardware it runs on: one Driver per robot,
  Sensors for moving objects, the rate, the machines its composites run on (``hosts``), and the
  topics and services of other ROS nodes that raise events of the program (``events``).
* **Constraint-based program** — robots (URDF, base type, placement, object frames on links),
  objects (placement, object frames), Tasks, the Solver, named configurations (paper §5),
  Monitors (condition → event, paper §4.1) and the Running sub-FSM (paper §6.2).
* **Task** — a chain between two object frames o1, o2 (or joints), the outputs it constrains, a
  controller and its gains, a setpoint generator, weights and priority, equality or inequality.

Any mapping may be replaced by ``{include: file.yaml}`` (a robot, task or program reused across
applications). Cross references (links, frames, events, names) are checked by :mod:`.checks`.
"""

from __future__ import annotations

import math
import re
from typing import Any, Literal

from itasc_core.composition.model import OutsideEventModel
from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator, model_validator

__all__ = ['Application', 'Program', 'Robot', 'RobotFrame', 'Object', 'ObjectFrame', 'Task', 'Controller',
           'Setpoint', 'Placement', 'Driver', 'Sensor', 'Solver', 'Monitor', 'ControllerSettings', 'Settings',
           'State', 'Transition', 'Running', 'FEATURES']

NAME = r'^[A-Za-z][A-Za-z0-9_]*$'
EVENT = r'^e_[A-Za-z0-9_]+$'
#: Feature coordinates per chain type (joint chains: the joints).
FEATURES = {'cartesian': ('x', 'y', 'z', 'rx', 'ry', 'rz'), 'distance': ('distance',)}

Vec3 = tuple[float, float, float]


class _Model(BaseModel):
    model_config = ConfigDict(extra='forbid', populate_by_name=True)


def _as_list(value: Any) -> Any:
    """Accept a scalar where a list is expected (``weights: 1.0``, ``on: e_done``)."""
    return [value] if isinstance(value, (int, float, str)) and not isinstance(value, bool) else value


class Placement(_Model):
    """A pose: translation [m] and roll-pitch-yaw [rad] (URDF convention)."""

    xyz: Vec3 = (0.0, 0.0, 0.0)
    rpy: Vec3 = (0.0, 0.0, 0.0)


# -- Constraint-based program: robots and objects --------------------------------------------------

class RobotFrame(Placement):
    """An object frame on a robot link (e.g. the TCP), offset from the link."""

    name: str = Field(pattern=NAME)
    link: str = Field(min_length=1)


class JointLimits(_Model):
    """Limits of one joint that override the URDF's (position in rad or m, velocity per second)."""

    lower: float | None = None
    upper: float | None = None
    velocity: float | None = Field(default=None, gt=0)

    @model_validator(mode='after')
    def _ordered(self) -> 'JointLimits':
        if self.lower is not None and self.upper is not None and self.lower >= self.upper:
            raise ValueError(f'lower ({self.lower}) must be below upper ({self.upper})')
        return self


class Robot(Placement):
    """A robot: kinematic model from a URDF (path relative to this file, or a file name under
    config/robots), its base (``fixed``, or ``planar``/``free_flyer`` for a mobile base) placed at
    ``xyz``/``rpy`` in the world, its object frames, and joint limits overriding the URDF's."""

    name: str = Field(pattern=NAME)
    urdf: str = Field(min_length=1)
    base: Literal['fixed', 'planar', 'free_flyer'] = 'fixed'
    frames: list[RobotFrame] = Field(default_factory=list)
    limits: dict[str, JointLimits] = Field(default_factory=dict)


class ObjectFrame(Placement):
    name: str = Field(pattern=NAME)


class ObjectMotion(_Model):
    """A moving object's trajectory: oscillating about its placement, per axis."""

    amplitude: tuple[float, float, float]
    period: float = Field(gt=0)


class Object(Placement):
    """An object without controllable DOF, at ``xyz``/``rpy``, moving along ``motion``, or where
    its Sensor says. ``size`` [m], the diameter of the sphere that shows it (an obstacle) in RViz,
    Foxglove and itasc-scene; Tasks measure distances to its frames, not to its surface."""

    name: str = Field(pattern=NAME)
    frames: list[ObjectFrame] = Field(default_factory=list)
    motion: ObjectMotion | None = None
    size: float | None = Field(default=None, gt=0)


# -- Task ----------------------------------------------------------------------------------------

class Controller(_Model):
    """A Constraint Controller: P or PID with feed-forward and saturation (paper §4.1 "CC")."""

    kind: Literal['p', 'pid'] = 'pid'
    kp: float = Field(default=1.0, ge=0)
    ki: float = Field(default=0.0, ge=0)
    kd: float = Field(default=0.0, ge=0)
    max_output: float = Field(default=math.inf, gt=0)


class Setpoint(_Model):
    """A Setpoint Generator (paper §4.1). ``value`` is in output space; a Cartesian Task may give a
    ``pose`` of o2 in o1 instead. ``hold`` keeps the output where the Task found it."""

    kind: Literal['hold', 'fixed', 'minimum_jerk', 'trapezoidal', 'periodic', 'topic']
    value: list[float] | None = None
    pose: Placement | None = None
    duration: float = Field(default=0.0, ge=0)
    max_velocity: list[float] | None = None
    max_acceleration: list[float] | None = None
    amplitude: list[float] | None = None
    period: float | None = Field(default=None, gt=0)
    offset: list[float] | None = None
    phase: list[float] | None = None
    topic: str | None = None

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


class Task(_Model):
    """A Task (paper §4.2): a virtual kinematic chain of ``type`` between object frames ``o1`` and
    ``o2`` (``robot/frame``, ``object/frame``, ``object`` or ``world``) or over ``joints``, the
    ``outputs`` it constrains, how (controller, setpoint), how much (weights) and with which
    ``priority`` (0 highest); an ``inequality`` keeps the outputs within ``d_min``/``d_max``."""

    name: str = Field(pattern=NAME)
    type: Literal['cartesian', 'distance', 'joint']
    o1: str | None = None
    o2: str | None = None
    joints: list[str] | None = None
    outputs: list[str] | None = None
    coordinates: Literal['xyz_log3', 'log6'] = 'xyz_log3'
    controller: Controller = Field(default_factory=Controller)
    setpoint: Setpoint | None = None
    weights: list[float] = Field(default_factory=lambda: [1.0])
    priority: int = Field(default=0, ge=0)
    constraint: Literal['equality', 'inequality'] = 'equality'
    d_min: list[float] | None = None
    d_max: list[float] | None = None

    _list = field_validator('weights', 'd_min', 'd_max', mode='before')(_as_list)

    @field_validator('weights')
    @classmethod
    def _positive(cls, value: list[float]) -> list[float]:
        if not value or any(w <= 0 for w in value):
            raise ValueError('weights must be > 0')
        return value

    @field_validator('d_min', 'd_max')
    @classmethod
    def _bounds(cls, value: list[float] | None, info: ValidationInfo) -> list[float] | None:
        if value is None:
            return value
        if info.data.get('type') == 'distance' and any(v < 0 for v in value):
            raise ValueError(f'a distance is never negative: {info.field_name} must be >= 0 (got {value})')
        low = info.data.get('d_min') if info.field_name == 'd_max' else None
        n = max(len(value), len(low or ()))
        if low is not None and not all(lo < hi for lo, hi in zip(low * n if len(low) == 1 else low,
                                                                  value * n if len(value) == 1 else value)):
            raise ValueError(f'd_max {value} must be above d_min {low}')
        return value

    @property
    def features(self) -> tuple[str, ...]:
        return FEATURES.get(self.type) or tuple(self.joints or ())

    @property
    def selected(self) -> tuple[str, ...]:
        return tuple(self.outputs) if self.outputs else self.features

    @model_validator(mode='after')
    def _consistent(self) -> 'Task':
        if self.type == 'joint':
            if not self.joints:
                raise ValueError("a 'joint' task needs joints")
            if self.o1 or self.o2:
                raise ValueError("a 'joint' task has joints, not o1/o2")
        elif not (self.o1 and self.o2):
            raise ValueError(f"a '{self.type}' task needs both o1 and o2")
        unknown = [o for o in self.outputs or () if o not in self.features]
        if unknown:
            raise ValueError(f'outputs {unknown} are not features of a {self.type} chain: {list(self.features)}')
        m = len(self.selected)
        for key in ('weights', 'd_min', 'd_max'):
            value = getattr(self, key)
            if value is not None and len(value) not in (1, m):
                raise ValueError(f'{key}: one value, or one per output ({m}), expected')
        if self.constraint == 'inequality':
            if self.d_min is None and self.d_max is None:
                raise ValueError('an inequality task needs d_min and/or d_max')
            if self.setpoint is not None:
                raise ValueError('an inequality task has bounds (d_min/d_max), not a setpoint')
        elif self.d_min is not None or self.d_max is not None:
            raise ValueError("d_min/d_max need 'constraint: inequality'")
        if self.setpoint is not None:
            self._check_setpoint(self.setpoint, m)
        return self

    def _check_setpoint(self, sp: Setpoint, m: int) -> None:
        if sp.pose is not None and self.type != 'cartesian':
            raise ValueError('a setpoint pose needs a cartesian task; give a value')
        for key in ('value', 'amplitude', 'offset', 'phase'):
            v = getattr(sp, key)
            if v is not None and len(v) not in ((1, m) if key != 'value' else (m,)):
                raise ValueError(f'setpoint {key} has {len(v)} values for {m} outputs {list(self.selected)}')


# -- Configurations, Monitors, Running sub-FSM -------------------------------------------------------------

class ControllerSettings(_Model):
    kp: float | None = Field(default=None, ge=0)
    ki: float | None = Field(default=None, ge=0)
    kd: float | None = Field(default=None, ge=0)
    max_output: float | None = Field(default=None, gt=0)


class Settings(_Model):
    """What a named configuration sets on one target (paper §5, §6.1 Run: "the task weights and
    priorities"): a Task's ``controller`` gains, its row ``weights`` and its ``priority`` level, or
    a Monitor's ``threshold``."""

    controller: ControllerSettings | None = None
    weights: list[float] | None = None
    priority: int | None = Field(default=None, ge=0)
    threshold: float | None = None

    _list = field_validator('weights', mode='before')(_as_list)

    @field_validator('weights')
    @classmethod
    def _positive(cls, value: list[float] | None) -> list[float] | None:
        if value is not None and (not value or any(not w > 0 for w in value)):
            raise ValueError('weights must be > 0')
        return value

    @property
    def for_task(self) -> bool:
        return self.controller is not None or self.weights is not None or self.priority is not None

    @model_validator(mode='after')
    def _something(self) -> 'Settings':
        if self.for_task == (self.threshold is not None):
            raise ValueError("set a task's controller, weights or priority, or a monitor's threshold")
        return self


class Monitor(_Model):
    """A Monitor (paper §4.1): raises ``event`` when ``condition`` starts to hold on ``watch``:
    ``<Task>.<output|setpoint|error|error_norm|progress>[index]`` or
    ``Solver.<solve_time|min_singular_value|damping>``."""

    name: str = Field(pattern=NAME)
    watch: str = Field(pattern=r'^[A-Za-z][A-Za-z0-9_]*\.[a-z_]+(\[[0-9]+\])?$')
    condition: Literal['above', 'below', 'outside', 'stale', 'nonfinite']
    threshold: float = 0.0
    band: tuple[float, float] | None = None
    timeout: float = Field(default=0.5, gt=0)
    event: str = Field(pattern=EVENT)
    enabled: bool = True

    @model_validator(mode='after')
    def _band(self) -> 'Monitor':
        if self.condition == 'outside' and self.band is None:
            raise ValueError("condition 'outside' needs band: [low, high]")
        return self


class State(_Model):
    """A state of the Running sub-FSM: on entry it makes ``tasks`` the active Tasks and
    ``monitors`` the active Monitors (omitted: unchanged), applies ``configure`` and raises
    ``raise``."""

    tasks: list[str] | None = None
    monitors: list[str] | None = None
    configure: list[str] = Field(default_factory=list)
    raise_: list[str] = Field(default_factory=list, alias='raise')

    @field_validator('raise_')
    @classmethod
    def _events(cls, value: list[str]) -> list[str]:
        bad = [e for e in value if not e.startswith('e_')]
        if bad:
            raise ValueError(f'event names start with e_: {bad}')
        return value


class Transition(_Model):
    source: str = Field(alias='from')
    target: str = Field(alias='to')
    when: list[str] = Field(min_length=1)

    _list = field_validator('when', mode='before')(_as_list)


class Running(_Model):
    """The application-specific Running sub-FSM (paper §6.2)."""

    initial: str
    states: dict[str, State] = Field(min_length=1)
    transitions: list[Transition] = Field(default_factory=list)


class Solver(_Model):
    """``wdls`` (weighted damped least squares, priorities by null-space projection; ``damping``
    the maximum damping near singularities) or ``qp`` (cascade of QPs with inequalities; ``backend``
    any qpsolvers solver; ``regularization`` the weight of the joint-velocity norm)."""

    kind: Literal['wdls', 'qp'] = 'wdls'
    backend: str = 'daqp'
    joint_weights: dict[str, float] = Field(default_factory=dict)
    damping: float = Field(default=0.1, ge=0)
    regularization: float = Field(default=1e-6, gt=0)
    position_limit_gain: float = Field(default=0.5, gt=0, le=1)

    @field_validator('joint_weights')
    @classmethod
    def _positive(cls, value: dict[str, float]) -> dict[str, float]:
        if any(w <= 0 for w in value.values()):
            raise ValueError('joint weights must be > 0')
        return value


class Program(_Model):
    """The Constraint-based program (paper §4.2)."""

    name: str = Field(default='itasc', pattern=NAME)
    robots: list[Robot] = Field(min_length=1)
    objects: list[Object] = Field(default_factory=list)
    tasks: list[Task] = Field(min_length=1)
    solver: Solver = Field(default_factory=Solver)
    configurations: dict[str, dict[str, Settings]] = Field(default_factory=dict)
    configure: list[str] = Field(default_factory=list)
    monitors: list[Monitor] = Field(default_factory=list)
    running: Running | None = None

    @field_validator('configurations')
    @classmethod
    def _names(cls, value: dict[str, Any]) -> dict[str, Any]:
        bad = [n for n in value if not re.match(NAME, n)]
        if bad:
            raise ValueError(f'configuration names must match {NAME}: {bad}')
        return value


# -- Application ------------------------------------------------------------------------------------

class Driver(_Model):
    """The Driver of one robot: ``simulated`` (``initial`` joint positions), or ``ros2_control``
    (an existing driver: ``joint_states`` topic, ``controller`` whose ``joints`` in order take
    ``interface`` commands on ``command_topic``, default ``/<controller>/commands``)."""

    robot: str
    kind: Literal['simulated', 'ros2_control']
    initial: dict[str, float] = Field(default_factory=dict)
    joint_states: str = '/joint_states'
    controller: str | None = Field(default=None, pattern=r'^[A-Za-z0-9_/]+$')
    interface: Literal['velocity', 'position', 'trajectory'] = 'velocity'
    joints: list[str] | None = None
    command_topic: str | None = None

    @model_validator(mode='after')
    def _complete(self) -> 'Driver':
        if self.kind == 'ros2_control' and not (self.controller and self.joints):
            raise ValueError("a 'ros2_control' driver needs controller and joints")
        if self.kind == 'simulated' and (self.controller or self.joints):
            raise ValueError("a 'simulated' driver takes no controller or joints")
        return self


class Sensor(_Model):
    """A pose Sensor of a moving object: ``geometry_msgs/PoseStamped`` (world frame) on ``topic``."""

    object: str
    kind: Literal['pose'] = 'pose'
    topic: str = Field(pattern=r'^/?[A-Za-z0-9_/]+$')


class Application(_Model):
    """The Application (paper §4.2): a Constraint-based program with its Drivers and Sensors."""

    name: str = Field(pattern=NAME)
    rate: float = Field(gt=0)
    program: Program
    drivers: list[Driver] = Field(min_length=1)
    sensors: list[Sensor] = Field(default_factory=list)
    #: Composites on other machines (README "Several machines"): the program's or a Task's name ->
    #: the name of the host whose agent runs it.
    hosts: dict[str, str] = Field(default_factory=dict)
    #: Outside events: messages and service calls of other ROS nodes (a gripper, a PLC bridge) that
    #: raise events of the program, for its Running sub-FSM to wait for.
    events: list[OutsideEventModel] = Field(default_factory=list)

    @model_validator(mode='after')
    def _placeable(self) -> 'Application':
        known = {self.program.name, *(task.name for task in self.program.tasks)}
        for name, host in self.hosts.items():
            if name not in known:
                raise ValueError(f"hosts places '{name}', which is neither the program nor one of its tasks; "
                                 f'known: {sorted(known)}')
            if not re.match(NAME, host):
                raise ValueError(f"host name {host!r} of '{name}' must match {NAME}")
        return self

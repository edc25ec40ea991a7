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

A section that configures one entity is that entity's parameter model (one source for the
entity's validation, this schema and its ROS parameters): a placement and an object's motion (the
Scene's), a controller (the Constraint Controller's gains), a setpoint (the Setpoint Generator's),
the solver's settings (the Solver's).
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING, Any, Literal

from itasc_core.composition.model import (MAX_RATE, MIN_RATE, OutsideEventModel, RunningStateModel,
                                         RunningTransitionModel)
from itasc_core.computation.conditions import CONDITIONS
from itasc_core.computation.parameters import FileModel, Names, TopicName, partial
from itasc_core.kinds import Registry, variants
from itasc_core.itasc.entities.scene_entity import ObjectMotion, Placement
from itasc_core.itasc.entities.solver_entity import SolverSettings
from itasc_core.itasc.solver.kind import SOLVERS
from itasc_drivers.drivers import DRIVERS
from itasc_tasks.controllers import CONTROLLERS
from itasc_tasks.entities.constraint_controller_entity import ControllerBase
from itasc_tasks.entities.setpoint_generator_entity import SetpointBase
from itasc_tasks.setpoints import SETPOINTS
from itasc_tasks.task_types import TASK_TYPES
from pydantic import ConfigDict, Field, TypeAdapter, ValidationInfo, field_validator, model_validator

__all__ = ['KIND_SECTIONS', 'Application', 'Program', 'Robot', 'RobotFrame', 'Object', 'ObjectFrame', 'Task',
           'Controller', 'Setpoint', 'Placement', 'ObjectMotion', 'Driver', 'Sensor', 'Solver', 'Monitor',
           'ControllerSettings', 'Settings', 'State', 'Transition', 'Running', 'TaskSwap', 'CompositionStep',
           'TaskBase', 'MonitorBase', 'DriverBase', 'SolverBase', 'SetpointBase']

#: A name (of an application, robot, object, frame, Task, Monitor...): a ROS name token of at most 64
#: characters (names are joined into namespaces and topics, which DDS bounds).
NAME = r'^[A-Za-z][A-Za-z0-9_]{0,63}$'
EVENT = r'^e_[A-Za-z0-9_]+$'


class _Model(FileModel):
    model_config = ConfigDict(populate_by_name=True)


def _as_list(value: Any) -> Any:
    """Accept a scalar where a list is expected (``weights: 1.0``, ``on: e_done``)."""
    return [value] if isinstance(value, (int, float, str)) and not isinstance(value, bool) else value


#: The sections whose kind is registered (:mod:`itasc_core.kinds`): the registry, the field that
#: names the kind and the suffix of each kind's section model.
KIND_SECTIONS: list[tuple[Registry[Any], str, str]] = [
    (TASK_TYPES, 'type', 'Task'), (CONDITIONS, 'condition', 'Monitor'), (CONTROLLERS, 'kind', ''),
    (SOLVERS, 'kind', ''), (DRIVERS, 'kind', 'Driver'), (SETPOINTS, 'kind', 'Setpoint')]

#: A Setpoint Generator: its kind and that kind's fields (one section per registered generator).
if TYPE_CHECKING:
    Setpoint = SetpointBase
else:
    Setpoint = variants(SetpointBase, SETPOINTS, field='kind', suffix='Setpoint')

#: A Constraint Controller: its law and that law's gains (one section per registered controller).
if TYPE_CHECKING:
    Controller = ControllerBase
else:
    Controller = variants(ControllerBase, CONTROLLERS, field='kind', suffix='')
_controller = TypeAdapter(Controller)


# -- Constraint-based program: robots and objects --------------------------------------------------

class RobotFrame(Placement):
    """An object frame on a robot link (e.g. the TCP), offset from the link."""

    name: str = Field(pattern=NAME)
    """The frame's name: Tasks refer to it as ``<robot>/<name>``."""
    link: str = Field(min_length=1)
    """The URDF link it is fixed to."""


class JointLimits(_Model):
    """Limits of one joint that override the URDF's (position in rad or m, velocity per second)."""

    lower: float | None = None
    """Lowest position [rad, or m for a prismatic joint]."""
    upper: float | None = None
    """Highest position [rad, or m]."""
    velocity: float | None = Field(default=None, gt=0)
    """Largest speed [rad/s, or m/s]."""

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
    """The robot's name: its frames are ``<name>/<frame>``, its topics under ``/<app>/<name>``."""
    urdf: str = Field(min_length=1)
    """URDF file: a path relative to this model file, or a file name under ``config/robots``."""
    base: Literal['fixed', 'planar', 'free_flyer'] = 'fixed'
    """``fixed``, or a mobile base: ``planar`` (x, y, yaw) or ``free_flyer`` (6 DOF)."""
    frames: list[RobotFrame] = Field(default_factory=list)
    """Object frames on the robot's links (e.g. the tool centre point)."""
    limits: dict[str, JointLimits] = Field(default_factory=dict)
    """Joint limits by joint name, overriding the URDF's."""


class ObjectFrame(Placement):
    name: str = Field(pattern=NAME)
    """The frame's name: Tasks refer to it as ``<object>/<name>``."""


class Object(Placement):
    """An object without controllable DOF, at ``xyz``/``rpy``, moving along ``motion``, or where
    its Sensor says. ``size`` [m], the diameter of the sphere that shows it (an obstacle) in RViz,
    Foxglove and itasc-scene; Tasks measure distances to its frames, not to its surface."""

    name: str = Field(pattern=NAME)
    """The object's name; ``<name>`` alone is its own frame."""
    frames: list[ObjectFrame] = Field(default_factory=list)
    """Frames fixed on the object."""
    motion: ObjectMotion | None = None
    """A known motion (an oscillation about the placement); omitted: the object stays or its Sensor moves it."""
    size: float | None = Field(default=None, gt=0)
    """Diameter [m] of the sphere that shows it; for display only."""


# -- Task ----------------------------------------------------------------------------------------

class TaskBase(_Model):
    """A Task (paper §4.2): a virtual kinematic chain of ``type`` (a registered task type: its fields
    say between which object frames, ``o1`` and ``o2``, or over which ``joints``), the ``outputs`` it
    constrains, how (controller, setpoint), how much (weights) and with which ``priority`` (0
    highest); an ``inequality`` keeps the outputs within ``d_min``/``d_max``."""

    name: str = Field(pattern=NAME)
    """The Task's name: its composite, topics (``<program>/<name>/...``) and events (``e_<name>_...``)."""
    type: str
    """The virtual kinematic chain, a registered task type."""
    outputs: Names | None = None
    """The features constrained, each once (omitted: all of the chain's)."""
    controller: Controller = Field(default_factory=lambda: _controller.validate_python({}))
    """The Constraint Controller."""
    setpoint: Setpoint | None = None
    """The Setpoint Generator (an equality Task)."""
    weights: list[float] = Field(default_factory=lambda: [1.0])
    """Weight of each constrained output in its priority level (one value: all)."""
    priority: int = Field(default=0, ge=0, le=2**32 - 1)
    """Priority level, 0 highest."""
    constraint: Literal['equality', 'inequality'] = 'equality'
    """``equality``: follow the setpoint; ``inequality``: stay within ``d_min``/``d_max``."""
    d_min: list[float] | None = None
    """Lower bound per output (one value: all) [m or rad]."""
    d_max: list[float] | None = None
    """Upper bound per output [m or rad]."""

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
        kind = str(info.data.get('type'))
        if kind in TASK_TYPES and TASK_TYPES[kind].nonnegative and any(v < 0 for v in value):
            raise ValueError(f'a {kind} is never negative: {info.field_name} must be >= 0 (got {value})')
        low = info.data.get('d_min') if info.field_name == 'd_max' else None
        n = max(len(value), len(low or ()))
        if low is not None and not all(lo < hi for lo, hi in zip(low * n if len(low) == 1 else low,
                                                                  value * n if len(value) == 1 else value)):
            raise ValueError(f'd_max {value} must be above d_min {low}')
        return value

    @property
    def kind(self) -> Any:
        """Its task type (:class:`itasc_tasks.task_types.TaskType`)."""
        return TASK_TYPES[self.type]

    @property
    def features(self) -> tuple[str, ...]:
        return self.kind.features(self)

    @property
    def selected(self) -> tuple[str, ...]:
        return tuple(self.outputs) if self.outputs else self.features

    @property
    def chain(self) -> dict[str, Any]:
        """The parameters of its chain (its task type's fields)."""
        return {key: getattr(self, key) for key in self.kind.Parameters.model_fields}

    @model_validator(mode='after')
    def _consistent(self) -> 'TaskBase':
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
        if getattr(sp, 'pose', None) is not None and not self.kind.pose_setpoints:
            raise ValueError(f'a setpoint pose needs a task whose chain is a pose (not {self.type}); give a value')
        # a setpoint's lists of numbers are per output: ``value`` one per output, any other (a periodic
        # amplitude, a profile's max_velocity) one for all or one per output
        for key in type(sp).model_fields:
            v = getattr(sp, key, None)
            if isinstance(v, list) and v and all(isinstance(x, (int, float)) for x in v) \
                    and len(v) not in ((1, m) if key != 'value' else (m,)):
                raise ValueError(f'setpoint {key} has {len(v)} values for {m} outputs {list(self.selected)}')


#: A Task: the common fields and those of its task type (one section per registered task type).
if TYPE_CHECKING:
    Task = TaskBase
else:
    Task = variants(TaskBase, TASK_TYPES, field='type', suffix='Task')


# -- Configurations, Monitors, Running sub-FSM -------------------------------------------------------------

ControllerSettings = partial(*(kind.Parameters for kind in CONTROLLERS.kinds().values()),
                             name='ControllerSettings',
                             doc="New gains of a Task's Constraint Controller (omitted: unchanged; only gains its "
                                 'controller has).')


class Settings(_Model):
    """What a named configuration sets on one target (paper §5, §6.1 Run: "the task weights and
    priorities"): a Task's ``controller`` gains, its row ``weights`` and its ``priority`` level, or
    a Monitor's ``threshold``."""

    controller: ControllerSettings | None = None  # type: ignore[valid-type]  # built from the controllers' gains
    """New controller gains of the Task."""
    weights: list[float] | None = None
    """New weights of the Task's outputs."""
    priority: int | None = Field(default=None, ge=0)
    """New priority level of the Task."""
    threshold: float | None = None
    """New threshold of the Monitor."""

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


class MonitorBase(_Model):
    """A Monitor (paper §4.1): raises ``event`` when ``condition`` (a registered condition, with its
    own fields) starts to hold on ``watch``: ``<Task>.<output|setpoint|error|error_norm|progress>[index]``
    or ``Solver.<solve_time|min_singular_value|damping>``."""

    name: str = Field(pattern=NAME)
    """The Monitor's name (a Running state lists the Monitors it runs)."""
    watch: str = Field(pattern=r'^[A-Za-z][A-Za-z0-9_]*\.[a-z_]+(\[[0-9]+\])?$')
    """What it watches: ``<Task>.<output|setpoint|error|error_norm|progress>[index]`` or
    ``Solver.<solve_time|min_singular_value|damping>``."""
    condition: str
    """When it fires: a registered condition."""
    event: str = Field(pattern=EVENT)
    """The event it raises once the condition starts to hold."""
    enabled: bool = True
    """Whether it runs from the start (a Running state may switch it)."""

    @property
    def condition_parameters(self) -> dict[str, Any]:
        """The parameters of its condition (its condition's fields)."""
        return {key: getattr(self, key) for key in CONDITIONS[self.condition].Parameters.model_fields}


#: A Monitor: the common fields and those of its condition (one section per registered condition).
if TYPE_CHECKING:
    Monitor = MonitorBase
else:
    Monitor = variants(MonitorBase, CONDITIONS, field='condition', suffix='Monitor')


class State(_Model, RunningStateModel):
    """A state of the Running sub-FSM: on entry it runs the composition steps ``compose``, makes
    ``tasks`` the active Tasks and ``monitors`` the active Monitors (omitted: unchanged), applies
    ``configure`` and raises ``raise`` (a state of the composition model's Running sub-FSM, with what
    the program switches)."""

    model_config = ConfigDict(frozen=False)

    compose: list[str] = Field(default_factory=list)
    """Composition steps of the program run on entry (``composition``), in order."""
    tasks: list[str] | None = None
    """The Tasks active in this state (omitted: the current ones stay)."""
    monitors: list[str] | None = None
    """The Monitors active in this state (omitted: the current ones stay)."""
    configure: list[str] = Field(default_factory=list)
    """Named configurations applied on entry."""

    @field_validator('raise_')
    @classmethod
    def _events(cls, value: list[str]) -> list[str]:
        bad = [e for e in value if not e.startswith('e_')]
        if bad:
            raise ValueError(f'event names start with e_: {bad}')
        return value


#: A transition of the Running sub-FSM: the composition model's.
Transition = RunningTransitionModel


class Running(_Model):
    """The application-specific Running sub-FSM (paper §6.2)."""

    initial: str
    """The state the sub-FSM starts in."""
    states: dict[str, State] = Field(min_length=1)
    """The states, by name."""
    transitions: list[Transition] = Field(default_factory=list)
    """The transitions between them."""


class SolverBase(SolverSettings):
    """The Solver (paper §4.1 "Solver"): a registered solver kind, its settings and the joints' weights."""

    joint_weights: dict[str, float] = Field(default_factory=dict)
    """Weight of each joint's velocity by joint name (default 1): a heavier joint moves less."""

    @field_validator('joint_weights')
    @classmethod
    def _positive(cls, value: dict[str, float]) -> dict[str, float]:
        if any(w <= 0 for w in value.values()):
            raise ValueError('joint weights must be > 0')
        return value


#: The Solver: its kind and that kind's settings (one section per registered solver).
if TYPE_CHECKING:
    Solver = SolverBase
else:
    Solver = variants(SolverBase, SOLVERS, field='kind', suffix='')
_solver = TypeAdapter(Solver)


class TaskSwap(_Model):
    """What a composition step replaces in a running Task: its Constraint Controller and/or its
    Setpoint Generator (the chain, outputs, weights and priority stay). The new one starts from
    where the Task is: a setpoint motion from the current output, a controller afresh."""

    controller: Controller | None = None
    """The new Constraint Controller."""
    setpoint: Setpoint | None = None
    """The new Setpoint Generator (an equality Task)."""

    @model_validator(mode='after')
    def _something(self) -> 'TaskSwap':
        if self.controller is None and self.setpoint is None:
            raise ValueError('swap a controller, a setpoint, or both')
        return self


class CompositionStep(_Model):
    """A composition step (paper §3.1: run-time re-composition): a change of the program's
    structure while it runs. Each composite it changes changes between two ticks, all of its part
    or nothing: first each swapped Task (``e_<Task>_composed``), then, if all of them did, the
    program (Tasks added, removed, the Solver swapped: ``e_<program>_composed``); a part that does
    not fit changes nothing of its composite, and ``e_<program>_compose_failed`` names why. A
    state of the Running sub-FSM runs it on entry (``compose``); an operator with
    ``<program ns>/coordinator/compose``."""

    add: list[Task] = Field(default_factory=list)
    """Tasks to add (each goes through its life-cycle until Running, then computes)."""
    remove: list[str] = Field(default_factory=list)
    """Tasks to remove (stopped in order, then gone from the ROS graph)."""
    swap: dict[str, TaskSwap] = Field(default_factory=dict)
    """Controllers and setpoint generators to replace, by Task."""
    solver: Solver | None = None
    """A Solver to replace the running one (e.g. ``wdls`` for ``qp``)."""

    @model_validator(mode='after')
    def _something(self) -> 'CompositionStep':
        if not (self.add or self.remove or self.swap or self.solver):
            raise ValueError('a composition step adds, removes or swaps something')
        return self


class Program(_Model):
    """The Constraint-based program (paper §4.2)."""

    name: str = Field(default='itasc', pattern=NAME)
    """The program composite's name."""
    robots: list[Robot] = Field(min_length=1)
    """The robots."""
    objects: list[Object] = Field(default_factory=list)
    """The objects and their frames."""
    tasks: list[Task] = Field(min_length=1)
    """The Tasks."""
    solver: Solver = Field(default_factory=lambda: _solver.validate_python({}))
    """The Solver."""
    configurations: dict[str, dict[str, Settings]] = Field(default_factory=dict)
    """Named configurations: name -> target (a Task or Monitor) -> settings (paper §5)."""
    configure: list[str] = Field(default_factory=list)
    """Configurations applied when the program is configured."""
    monitors: list[Monitor] = Field(default_factory=list)
    """The Monitors."""
    running: Running | None = None
    """The Running sub-FSM (omitted: every Task runs from the start)."""
    composition: dict[str, CompositionStep] = Field(default_factory=dict)
    """Named composition steps: Tasks added, removed, controllers, setpoints and the Solver swapped
    while the program runs."""

    @field_validator('configurations')
    @classmethod
    def _names(cls, value: dict[str, Any]) -> dict[str, Any]:
        bad = [n for n in value if not re.match(NAME, n)]
        if bad:
            raise ValueError(f'configuration names must match {NAME}: {bad}')
        return value

    @field_validator('composition')
    @classmethod
    def _step_names(cls, value: dict[str, Any]) -> dict[str, Any]:
        bad = [n for n in value if not re.match(NAME, n) or n == 'failed']
        if bad:
            raise ValueError(f"composition step names must match {NAME} and not be 'failed': {bad}")
        return value

    @property
    def every_task(self) -> list[Task]:
        """The Tasks, and those composition steps add."""
        return [*self.tasks, *(t for step in self.composition.values() for t in step.add)]


# -- Application ------------------------------------------------------------------------------------

class DriverBase(_Model):
    """The Driver of one robot (paper §4.1 "Driver"): a registered driver kind and its fields."""

    robot: str
    """The robot it drives."""
    kind: str
    """A registered driver: ``simulated`` (integrates the commanded velocities) or ``ros2_control``
    (an existing driver); its fields follow."""
    silent_after: float | None = Field(default=None, gt=0)
    """How long the driver may report no joint state before its watchdog puts the application in
    Safety [s]; none: 20 periods of the application's rate, at least 0.25 s."""

    @property
    def driver(self) -> Any:
        """Its kind (:class:`itasc_drivers.drivers.Driver`)."""
        return DRIVERS[self.kind]


#: A Driver: the robot and the fields of its kind (one section per registered driver).
if TYPE_CHECKING:
    Driver = DriverBase
else:
    Driver = variants(DriverBase, DRIVERS, field='kind', suffix='Driver')


class Sensor(_Model):
    """A pose Sensor of a moving object: ``geometry_msgs/PoseStamped`` (world frame) on ``topic``."""

    object: str
    """The object whose pose it measures."""
    kind: Literal['pose'] = 'pose'
    """``pose``: ``geometry_msgs/PoseStamped`` in the world frame."""
    topic: TopicName
    """The topic it reads."""


class Application(_Model):
    """The Application (paper §4.2): a Constraint-based program with its Drivers and Sensors."""

    name: str = Field(pattern=NAME)
    """The application's name: its root namespace ``/<name>``."""
    rate: float = Field(ge=MIN_RATE, le=MAX_RATE)
    """The control rate [Hz]."""
    program: Program
    """The Constraint-based program."""
    drivers: list[Driver] = Field(min_length=1)
    """One Driver per robot."""
    sensors: list[Sensor] = Field(default_factory=list)
    """Sensors of moving objects."""
    hosts: dict[str, str] = Field(default_factory=dict)
    """Composites on other machines (README "Several machines"): the program's or a Task's name ->
    the name of the host whose agent runs it."""
    events: list[OutsideEventModel] = Field(default_factory=list)
    """Outside events: messages and service calls of other ROS nodes (a gripper, a PLC bridge) that
    raise events of the program, for its Running sub-FSM to wait for."""

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

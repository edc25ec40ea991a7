"""Cross-reference checks of an iTaSC application model, before anything starts (paper §3.3's
lesson: a newcomer must be able to change a model with confidence).

What a schema cannot see: URDF files that do not exist or do not load, link names the URDF does
not have (checked against the kinematic model Pinocchio builds), object frames and joints that no
robot or object has, duplicate names, events the Running sub-FSM waits for that nobody raises,
configurations, Tasks and Monitors that are not defined, Drivers and Sensors of unknown robots and
objects, outside events of message or service types that are not installed or fields they lack.
Every error is a :class:`ModelError` naming the file (the included one, if the faulty part came
from an include), the path inside it and what was expected.
"""

from __future__ import annotations

import os
import re
import sys
import tempfile
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import pinocchio as pin
from itasc_core.communication.event_names import (COMPOSE_FAILED, COMPOSED, JOINTS_MISSING, LIFE_CYCLE,
                                                  SOLVER_STATUSES, event, solver_status)
from itasc_core.composition.checks import check_outside_event
from itasc_core.composition.loader import MAX_BYTES, ModelError, format_loc, source_of
from itasc_core.composition.model import COMPOSITE_NODES, switching_forever
from itasc_core.itasc.robot import Robot as RobotModel
from itasc_drivers.drivers import DrivenRobot

from .locations import config_dirs
from .schema import Application, Program, Task

__all__ = ['check', 'load_robot', 'joint_limits', 'driven_robot',
           'SOLVER_EVENTS', 'TASK_QUANTITIES', 'SOLVER_QUANTITIES', 'RESERVED', 'AS_CONFIGURED', 'VECTORS',
           'MAX_URDF_BYTES']

Loc = tuple[Any, ...]

SOLVER_EVENTS = tuple(solver_status(s) for s in SOLVER_STATUSES)
#: What a Monitor may watch of a Task (TaskState fields, and the setpoint's progress) and of the Solver.
TASK_QUANTITIES = ('output', 'setpoint', 'error', 'error_norm', 'progress')
SOLVER_QUANTITIES = ('solve_time', 'min_singular_value', 'damping')
#: The Task quantities that have one value per output (the others are one number).
VECTORS = ('output', 'setpoint', 'error')
#: Entity names of the Constraint-based program composite that Tasks and Monitors may not take.
RESERVED = ('Scene', 'Solver')
#: A Task composite's Running state before any configuration event (see ``transform``).
AS_CONFIGURED = 'as_configured'
#: The largest URDF read (the shipped ones are about 6 kB).
MAX_URDF_BYTES = 16 * MAX_BYTES


@contextmanager
def _stderr_kept() -> Iterator[Callable[[], str]]:
    """What the C++ URDF parser prints on file descriptor 2 (``Error: ... at line 103 in
    .../urdfdom/...``) while the block runs: if the block fails, kept out of the output and handed
    to its error (yields what was said, its source locations left out), so that the model's error
    stays one line; if not, written out after it (a warning of the parser, or what another thread
    wrote meanwhile), so nothing is lost."""
    with tempfile.TemporaryFile() as kept:
        sys.stderr.flush()
        saved = os.dup(2)
        os.dup2(kept.fileno(), 2)
        text: list[str] = []
        failed = False
        try:
            yield lambda: ' '.join(text)
        except BaseException:
            failed = True
            raise
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            kept.seek(0)
            said = kept.read()
            if failed:
                text.append(re.sub(r'\s*at line \d+ in \S+', '', said.decode(errors='replace')).strip())
            elif said:
                os.write(2, said)


@lru_cache(maxsize=32)
def load_robot(name: str, urdf: str, base: str) -> RobotModel:
    """The kinematic model of a robot (cached: checks and transform both need it). What the URDF
    parser prints on stderr when it refuses the file is part of the error raised, not printed."""
    try:
        with _stderr_kept() as said:
            return RobotModel(name, urdf, base=base)
    except (ValueError, RuntimeError) as err:
        raise type(err)(' '.join(f'{err} {said()}'.split())) from None


def joint_limits(robots) -> tuple[list[str], dict[str, list[float]]]:
    """The joints of ``robots`` in order and their ``lower``/``upper``/``velocity_limit``: the
    URDF's, overridden by the model's ``limits`` (the Solver plans and the simulated robot moves
    within the same limits)."""
    models = [load_robot(r.name, r.urdf, r.base) for r in robots]
    joints = [j for m in models for j in m.joint_names]
    limits = {key: [float(v) for m in models for v in getattr(m, key)] for key in ('lower', 'upper', 'velocity_limit')}
    for robot in robots:
        for joint, override in robot.limits.items():
            i = joints.index(joint)
            for key, value in (('lower', override.lower), ('upper', override.upper),
                               ('velocity_limit', override.velocity)):
                if value is not None:
                    limits[key][i] = float(value)
    return joints, limits


def driven_robot(robot, rate: float) -> DrivenRobot:
    """What a Driver kind is told of the robot it drives (a model's robot, its URDF resolved)."""
    joints, limits = joint_limits([robot])
    return DrivenRobot(name=robot.name, urdf=robot.urdf, base=robot.base, joints=joints, limits=limits, rate=rate)


@dataclass
class _Where:
    """Turns a location in the loaded tree into the file and path a ModelError names."""

    sources: dict[Loc, Path]
    root: Loc

    def error(self, loc: Loc, message: str) -> ModelError:
        path, inner = source_of(self.root + loc, self.sources)
        return ModelError(str(path), format_loc(inner), message)

    def file(self, loc: Loc) -> Path:
        return source_of(self.root + loc, self.sources)[0]

    def include_site(self, loc: Loc) -> Loc | None:
        """Where the include that brought ``loc`` in stands (None: in the model file itself)."""
        full = self.root + loc
        site = max((p for p in self.sources if full[:len(p)] == p), key=len)
        return site[len(self.root):] if len(site) > len(self.root) else None

    def included_error(self, site: Loc, message: str) -> ModelError:
        """An error at the include at ``site``, named in the file that includes it."""
        path, inner = source_of(self.root + site[:-1], self.sources)
        return ModelError(str(path), format_loc(inner + (site[-1], 'include')), message)


def check(app: Application, sources: dict[Loc, Path], *, root: Loc = ('application',)) -> Application:
    """Check ``app``; raise the first :class:`ModelError`. Returns the application with every
    robot's URDF reference resolved to an absolute path."""
    where = _Where(sources, root)
    program = app.program
    _unique(where, [('program', 'robots', i, 'name') for i in range(len(program.robots))]
            + [('program', 'objects', i, 'name') for i in range(len(program.objects))],
            [r.name for r in program.robots] + [o.name for o in program.objects], 'robot or object name',
            reserved=('world',))
    robots = {}
    for i, robot in enumerate(program.robots):
        robots[robot.name] = _robot(where, ('program', 'robots', i), robot)
    resolved = app.model_copy(deep=True)
    for robot in resolved.program.robots:
        robot.urdf = robots[robot.name][0]
    joints = {name: list(model.joint_names) for name, (_, model) in robots.items()}
    _distinct_joints(where, program, joints)
    _objects(where, program)
    _tasks(where, program, robots={r.name: r for r in program.robots}, models={n: m for n, (_, m) in robots.items()},
           joints=[j for js in joints.values() for j in js])
    _monitors(where, program)
    _configurations(where, program)
    _outside_events(where, app)
    _composition(where, program, [j for js in joints.values() for j in js])
    _life_cycle(where, app)
    _running(where, program, outside=[e.event for e in app.events])
    _solver(where, ('program', 'solver'), program.solver, [j for js in joints.values() for j in js])
    _drivers(where, resolved, joints)
    _sensors(where, app)
    return resolved


def _unique(where: _Where, locs: list[Loc], names: list[str], what: str, *, reserved: Iterable[str] = ()) -> None:
    seen: dict[str, Loc] = {}
    for loc, name in zip(locs, names):
        if name in seen:
            first, second = where.include_site(seen[name]), where.include_site(loc)
            if first is not None and second is not None and first != second \
                    and where.file(seen[name]) == where.file(loc):  # one file, included twice
                raise where.included_error(second, f"duplicate {what} '{name}': '{where.file(loc)}' is included "
                                           f'twice (first at {format_loc(first)})')
            raise where.error(loc, f"duplicate {what} '{name}'")
        if name in reserved:
            raise where.error(loc, f"'{name}' is reserved: choose another {what}")
        seen[name] = loc


# -- robots and objects -------------------------------------------------------------------------------

def _robot(where: _Where, loc: Loc, robot) -> tuple[str, RobotModel]:
    urdf = _find_urdf(where.file(loc + ('urdf',)).parent, robot.urdf)
    if urdf is None:
        raise where.error(loc + ('urdf',), f"URDF '{robot.urdf}' not found (relative to this file, "
                          f'or under config/robots; a regular file of at most {MAX_URDF_BYTES} bytes)')
    try:
        model = load_robot(robot.name, str(urdf), robot.base)
    except (ValueError, RuntimeError) as err:
        raise where.error(loc + ('urdf',), f"URDF '{robot.urdf}' cannot be loaded: {err}") from None
    links = [f.name for f in model.model.frames if f.type == pin.FrameType.BODY]
    _unique(where, [loc + ('frames', k, 'name') for k in range(len(robot.frames))],
            [f.name for f in robot.frames], f"frame name on robot '{robot.name}'")
    for k, frame in enumerate(robot.frames):
        if frame.link not in links:
            raise where.error(loc + ('frames', k, 'link'),
                              f"robot '{robot.name}' has no link '{frame.link}'; links: {links}")
        if frame.name in links:
            raise where.error(loc + ('frames', k, 'name'), f"'{frame.name}' is already a link of '{robot.name}'")
    if model.crossed_limits:
        raise where.error(loc + ('urdf',), f"URDF '{robot.urdf}': the lower limit of {', '.join(model.crossed_limits)} "
                          'is above its upper limit')
    for joint, override in robot.limits.items():
        if joint not in model.joint_names:
            raise where.error(loc + ('limits', joint), f"robot '{robot.name}' has no joint '{joint}'; "
                              f'joints: {model.joint_names}')
        i = model.joint_names.index(joint)
        lower = model.lower[i] if override.lower is None else override.lower
        upper = model.upper[i] if override.upper is None else override.upper
        if lower > upper:
            raise where.error(loc + ('limits', joint), f'lower {lower:g} is above upper {upper:g} '
                              f"(the URDF's: [{model.lower[i]:g}, {model.upper[i]:g}])")
    return str(urdf), model


def _distinct_joints(where: _Where, program: Program, joints: dict[str, list[str]]) -> None:
    """The Scene and the Solver know a joint by its name: two robots must not share one."""
    owner: dict[str, str] = {}
    for i, robot in enumerate(program.robots):
        shared = [j for j in joints[robot.name] if j in owner]
        if shared:
            raise where.error(('program', 'robots', i, 'urdf'), (
                f"robot '{robot.name}' has joints of the same names as robot '{owner[shared[0]]}' "
                f"({', '.join(shared)}); the joints of a program's robots are known by name, so each robot "
                "needs a URDF whose joints are its own (e.g. generated with a prefix, as xacro's prefix "
                "argument does)"))
        owner.update(dict.fromkeys(joints[robot.name], robot.name))


def _find_urdf(directory: Path, reference: str) -> Path | None:
    """The URDF file ``reference`` names: a regular file (not a device or pipe) of sane size."""
    candidates = [directory / reference] + [d / 'robots' / reference for d in config_dirs()]
    return next((c.resolve() for c in candidates if c.is_file() and c.stat().st_size <= MAX_URDF_BYTES), None)


def _objects(where: _Where, program: Program) -> None:
    for i, obj in enumerate(program.objects):
        _unique(where, [('program', 'objects', i, 'frames', k, 'name') for k in range(len(obj.frames))],
                [f.name for f in obj.frames], f"frame name on object '{obj.name}'", reserved=('origin',))


def frames_of(program: Program, models: dict[str, RobotModel]) -> dict[str, list[str]]:
    """Every frame a Task may name, by owner: ``robot/frame``, ``object/frame``, ``object``, ``world``."""
    frames: dict[str, list[str]] = {'world': ['']}
    for robot in program.robots:
        links = [f.name for f in models[robot.name].model.frames if f.type == pin.FrameType.BODY]
        frames[robot.name] = [f.name for f in robot.frames] + links
    for obj in program.objects:
        frames[obj.name] = ['', 'origin'] + [f.name for f in obj.frames]
    return frames


# -- tasks ----------------------------------------------------------------------------------------------

def task_locations(program: Program) -> list[tuple[Loc, Task]]:
    """Every Task of the program and of its composition steps, with where it is in the model."""
    return [(('program', 'tasks', i), t) for i, t in enumerate(program.tasks)] + \
        [(('program', 'composition', name, 'add', i), t) for name, step in program.composition.items()
         for i, t in enumerate(step.add)]


def _tasks(where: _Where, program: Program, *, robots: dict, models: dict[str, RobotModel],
           joints: list[str]) -> None:
    located = task_locations(program)
    _unique(where, [loc + ('name',) for loc, _ in located], [t.name for _, t in located], 'task name',
            reserved=RESERVED + tuple(f'Robot_{r}' for r in robots))
    frames = frames_of(program, models)
    for loc, task in located:
        for end in ('o1', 'o2'):
            address = task.chain.get(end)
            if address is None:
                continue
            owner, _, frame = address.partition('/')
            if owner not in frames or frame not in frames[owner]:
                known = [f'{o}/{f}' if f else o for o, fs in frames.items() for f in fs if f != 'origin']
                raise where.error(loc + (end,), f"unknown frame '{address}'; frames: {known}")
        if task.chain.get('o1') is not None and task.chain.get('o1') == task.chain.get('o2'):
            raise where.error(loc + ('o2',), 'o1 and o2 must be different frames')
        for k, joint in enumerate(task.chain.get('joints') or ()):
            if joint not in joints:
                raise where.error(loc + ('joints', k), f"unknown joint '{joint}'; joints: {joints}")


# -- monitors, configurations, Running sub-FSM ---------------------------------------------------------------

def _monitors(where: _Where, program: Program) -> None:
    tasks = {t.name: t for t in program.tasks}
    _unique(where, [('program', 'monitors', i, 'name') for i in range(len(program.monitors))],
            [m.name for m in program.monitors], 'monitor name', reserved=RESERVED + COMPOSITE_NODES + tuple(tasks))
    for i, monitor in enumerate(program.monitors):
        target, _, quantity = monitor.watch.partition('.')
        quantity = quantity.split('[')[0]
        loc = ('program', 'monitors', i, 'watch')
        if target == 'Solver':
            if quantity not in SOLVER_QUANTITIES:
                raise where.error(loc, f"the Solver has no '{quantity}'; expected one of {list(SOLVER_QUANTITIES)}")
        elif target not in tasks:
            raise where.error(loc, f"unknown task '{target}'; expected a task {sorted(tasks)} or Solver")
        elif quantity not in TASK_QUANTITIES:
            raise where.error(loc, f"a task has no '{quantity}'; expected one of {list(TASK_QUANTITIES)}")
        elif quantity == 'progress' and tasks[target].constraint == 'inequality':
            raise where.error(loc, f"inequality task '{target}' has no setpoint, hence no progress")
        _index(where, loc, monitor.watch, tasks[target].selected if quantity in VECTORS and target in tasks else None)


def _index(where: _Where, loc: Loc, watch: str, values: tuple[str, ...] | None) -> None:
    """``<quantity>[i]`` names one of the values of a vector quantity."""
    if '[' not in watch:
        return
    index = int(watch[watch.index('[') + 1:-1])
    if values is None:
        raise where.error(loc, f"'{watch}': '{watch.split('[')[0]}' is one number and takes no index")
    if index >= len(values):
        raise where.error(loc, f"'{watch}': index {index} is out of range: {len(values)} values {list(values)}")


def _configurations(where: _Where, program: Program) -> None:
    tasks = {t.name: t for t in program.every_task}
    monitors = {m.name: m for m in program.monitors}
    for name, targets in program.configurations.items():
        for target, settings in targets.items():
            loc = ('program', 'configurations', name, target)
            if target in tasks:
                if not settings.for_task:
                    raise where.error(loc, "a configuration sets a task's controller, weights or priority, "
                                      'not a threshold')
                gains = type(tasks[target].controller).model_fields
                changed: dict[str, Any] = {} if settings.controller is None else \
                    settings.controller.model_dump(exclude_none=True)
                for key in changed:
                    if key not in gains:
                        raise where.error(loc + ('controller', key), f"task '{target}' has a "
                                          f"{tasks[target].controller.kind} controller, without {key}; its "
                                          f"gains: {[g for g in gains if g != 'kind']}")
                m = len(tasks[target].selected)
                if settings.weights is not None and len(settings.weights) not in (1, m):
                    raise where.error(loc + ('weights',), f'one value, or one per output ({m}), expected '
                                      f'(got {len(settings.weights)})')
            elif target in monitors:
                if settings.threshold is None:
                    raise where.error(loc, "a configuration sets a monitor's threshold, not a controller")
                if 'threshold' not in monitors[target].condition_parameters:
                    raise where.error(loc + ('threshold',), f"monitor '{target}' ({monitors[target].condition}) has "
                                      'no threshold')
            else:
                raise where.error(loc, f"unknown task or monitor '{target}'; tasks: {sorted(tasks)}, "
                                  f'monitors: {sorted(monitors)}')
    for k, name in enumerate(program.configure):
        if name not in program.configurations:
            raise where.error(('program', 'configure', k),
                              f"unknown configuration '{name}'; known: {sorted(program.configurations)}")


def raised_events(program: Program, robots: Iterable[str], outside: Iterable[str] = ()) -> set[str]:
    """Every event raised inside the Constraint-based program that its Coordinator can hear
    (``outside``: those the application's outside events raise in it)."""
    events = {m.event for m in program.monitors} | set(SOLVER_EVENTS) | set(outside)
    events |= {event(r, JOINTS_MISSING) for r in robots}
    composers = [program.name] * bool(program.composition) + [t for s in program.composition.values() for t in s.swap]
    events |= {event(c, answer) for c in composers for answer in (COMPOSED, COMPOSE_FAILED)}
    if program.running is not None:
        events |= {e for s in program.running.states.values() for e in s.raise_}
    return events


def _running(where: _Where, program: Program, *, outside: Iterable[str] = ()) -> None:
    fsm = program.running
    if fsm is None:
        return
    states = sorted(fsm.states)
    if fsm.initial not in fsm.states:
        raise where.error(('program', 'running', 'initial'), f"unknown state '{fsm.initial}'; states: {states}")
    known = {'tasks': {t.name for t in program.every_task}, 'monitors': {m.name for m in program.monitors},
             'configure': set(program.configurations), 'compose': set(program.composition)}
    what = {'tasks': 'task', 'monitors': 'monitor', 'configure': 'configuration', 'compose': 'composition step'}
    for name, state in fsm.states.items():
        for field, names in known.items():
            for k, item in enumerate(getattr(state, field) or ()):
                if item not in names:
                    raise where.error(('program', 'running', 'states', name, field, k),
                                      f"unknown {what[field]} '{item}'; known: {sorted(names)}")
    events = raised_events(program, [r.name for r in program.robots], outside)
    for i, transition in enumerate(fsm.transitions):
        loc = ('program', 'running', 'transitions', i)
        for end, key in ((transition.source, 'from'), (transition.target, 'to')):
            if end not in fsm.states:
                raise where.error(loc + (key,), f"unknown state '{end}'; states: {states}")
        for k, name in enumerate(transition.when):
            if name not in events:
                raise where.error(loc + ('when', k), f"event '{name}' is raised by nobody; raised: {sorted(events)}")
    cycle = switching_forever({name: state.raise_ for name, state in fsm.states.items()},
                              [(t.source, t.target, t.when) for t in fsm.transitions])
    if cycle:
        raise where.error(('program', 'running', 'states', cycle[0], 'raise'), f"states {' -> '.join(cycle)} would "
                          'switch forever: each raises on entry an event that leaves it for the next')


# -- composition steps ----------------------------------------------------------------------------------------

def _composition(where: _Where, program: Program, joints: list[str]) -> None:
    """What a composition step names exists in some structure the program can have (which Tasks
    run when it runs depends on the steps before it: the Composer checks that then), a swapped
    setpoint fits its Task, and no step removes a Task a Monitor watches (that would never fit)."""
    tasks = {t.name: t for t in program.every_task}
    watched = {m.watch.partition('.')[0]: m.name for m in program.monitors}
    for name, step in program.composition.items():
        at = ('program', 'composition', name)
        for k, task in enumerate(step.remove):
            if task not in tasks:
                raise where.error(at + ('remove', k), f"unknown task '{task}'; tasks: {sorted(tasks)}")
            if task in watched:
                raise where.error(at + ('remove', k), f"task '{task}' cannot be removed: Monitor "
                                  f"'{watched[task]}' watches it")
        for task, swap in step.swap.items():
            if task not in tasks:
                raise where.error(at + ('swap', task), f"unknown task '{task}'; tasks: {sorted(tasks)}")
            replaced = tasks[task].model_dump(by_alias=True)
            replaced.update({key: getattr(swap, key).model_dump(by_alias=True)
                             for key in ('controller', 'setpoint') if getattr(swap, key) is not None})
            try:
                type(tasks[task]).model_validate(replaced)  # the same task type's section
            except ValueError as err:
                message = err.errors()[0]['msg'] if hasattr(err, 'errors') else str(err)
                raise where.error(at + ('swap', task), f"does not fit task '{task}': {message}") from None
        if step.solver is not None:
            _solver(where, at + ('solver',), step.solver, joints)


# -- solver, drivers, sensors ---------------------------------------------------------------------------------

def _solver(where: _Where, loc: Loc, solver, joints: list[str]) -> None:
    for joint in solver.joint_weights:
        if joint not in joints:
            raise where.error(loc + ('joint_weights', joint), f"unknown joint '{joint}'; joints: {joints}")


def _drivers(where: _Where, app: Application, joints: dict[str, list[str]]) -> None:
    driven: dict[str, int] = {}
    for i, driver in enumerate(app.drivers):
        loc = ('drivers', i)
        if driver.robot not in joints:
            raise where.error(loc + ('robot',), f"unknown robot '{driver.robot}'; robots: {sorted(joints)}")
        if driver.robot in driven:
            raise where.error(loc + ('robot',), f"robot '{driver.robot}' already has a driver "
                              f'(drivers[{driven[driver.robot]}])')
        driven[driver.robot] = i
        model = next(r for r in app.program.robots if r.name == driver.robot)
        problem = driver.driver.problem(driver, robot=driven_robot(model, app.rate))
        if problem is not None:
            raise where.error(loc + problem[0], problem[1])
    for robot in joints:
        if robot not in driven:
            raise where.error(('drivers',), f"robot '{robot}' has no driver")


def _life_cycle(where: _Where, app: Application) -> None:
    """What the model raises (Monitors, the Running sub-FSM's states, outside events) is not what
    the runtime says to or of a composite (``e_itasc_stop`` raised by a state stopped the program
    from inside and the run hung), and no configuration is named after such a word (``stop`` is
    commanded to a Task as ``e_<Task>_stop``)."""
    program = app.program
    composites = [app.name, program.name] + [t.name for t in program.every_task]
    life_cycle = {event(c, word): c for c in composites for word in LIFE_CYCLE}
    raised: list[tuple[Loc, str]] = [(('program', 'monitors', i, 'event'), m.event)
                                     for i, m in enumerate(program.monitors)]
    if program.running is not None:
        raised += [(('program', 'running', 'states', name, 'raise', k), e)
                   for name, state in program.running.states.items() for k, e in enumerate(state.raise_)]
    raised += [(('events', i, 'event'), outside.event) for i, outside in enumerate(app.events)]
    for loc, name in raised:
        if name in life_cycle:
            raise where.error(loc, f"'{name}' is an event of the life cycle of composite '{life_cycle[name]}': "
                              'the runtime raises it, a model does not')
    for name in program.configurations:
        if name in LIFE_CYCLE or name == AS_CONFIGURED:
            raise where.error(('program', 'configurations', name), f"'{name}' is reserved (a word of the "
                              'life cycle, or the configuration a Task starts in): choose another configuration name')


def _outside_events(where: _Where, app: Application) -> None:
    for i, outside in enumerate(app.events):
        problem = check_outside_event(outside)
        if problem is not None:
            raise where.error(('events', i, problem[0]), problem[1])


def _sensors(where: _Where, app: Application) -> None:
    objects = [o.name for o in app.program.objects]
    sensed: set[str] = set()
    for i, sensor in enumerate(app.sensors):
        if sensor.object not in objects:
            raise where.error(('sensors', i, 'object'), f"unknown object '{sensor.object}'; objects: {objects}")
        if sensor.object in sensed:
            raise where.error(('sensors', i, 'object'), f"object '{sensor.object}' already has a sensor")
        sensed.add(sensor.object)

"""From the iTaSC application model to the generic composition model the runtime executes (paper
§4.2, Fig. 2: three levels of composition; §3 the Composition Pattern at each level).

::

    <application>                      rate; Drivers and Sensors, then the program, every tick
      Driver_<robot>                   its driver kind's entity (SimulatedRobot, Ros2ControlAdapter, ...)
      Sensor_<object>                  PoseSensor
      <program> (itasc)                Constraint-based program
        Robot_<robot>                  RobotEntity: driver joint state -> model order
        Scene                          SceneEntity: relations between the Tasks' object frames
        <Task> ...                     Task composite: VKC, CO, SPG, CC, Rows
        Solver                         SolverEntity: rows of all Tasks -> joint velocities
        monitors, configurations (Monitor thresholds), Running sub-FSM

The Running sub-FSM of the program becomes the program composite's: entering a state raises
``e_<program>_compose_<step>`` (its composition steps), ``e_<Task>_activate``/``_deactivate`` (its
Scheduler switches Tasks), ``e_<monitor>_on``/``_off`` (Monitors), the state's configurations and
its own events.

A composition step of the program (paper §3.1) becomes a step of the program composite (Tasks
added with their connections, removed, the Solver swapped) whose swaps of a Task's controller or
setpoint generator are a step of that Task composite, of the same name (``children``: each
composite's Composer changes only its own entities). The Scene relates the frames of every Task a
step may add from the start. A configuration's settings live in
the Configurator of the composite whose entities they concern (paper §5.1: each composite's
Configurator configures its own entities): Monitor thresholds in the program's, which applies
``e_<configuration>``; controller gains, row weights and the priority level in the Task's. The
program addresses those to each Task concerned as ``e_<Task>_<configuration>``
(:mod:`itasc_core.communication.event_names`); the Task's Running sub-FSM, one state per
configuration, enters that state and raises ``e_<configuration>`` in the Task, which its
Configurator applies and answers with ``e_<configuration>_applied`` (paper Fig. 3).
"""

from __future__ import annotations

import math
from typing import Any

from itasc_core.communication.event_names import (ACTIVATE, DEACTIVATE, OFF, ON, SAFETY_EVENT, compose_step, event,
                                                  named, to_child)
from itasc_core.composition.model import (CompositeModel, CompositionStepModel, ConnectionModel, EntityModel,
                                          MonitorModel, RunningModel, SafetyModel)

from .checks import AS_CONFIGURED, SOLVER_QUANTITIES, driven_robot, joint_limits
from .schema import Application, CompositionStep, Driver, Monitor, Program, Solver, Task, TaskSwap

__all__ = ['to_composition', 'KINDS']

KINDS = {
    'robot': 'itasc_core.itasc.entities.robot_entity:RobotEntity',
    'scene': 'itasc_core.itasc.entities.scene_entity:SceneEntity',
    'solver': 'itasc_core.itasc.entities.solver_entity:SolverEntity',
    'vkc': 'itasc_tasks.entities.vkc_entity:VKCEntity',
    'co': 'itasc_tasks.entities.constraint_output_entity:ConstraintOutputEntity',
    'spg': 'itasc_tasks.entities.setpoint_generator_entity:SetpointGeneratorEntity',
    'cc': 'itasc_tasks.entities.constraint_controller_entity:ConstraintControllerEntity',
    'rows': 'itasc_tasks.entities.constraint_rows_entity:ConstraintRowsEntity',
    'pose': 'itasc_drivers.pose_sensor:PoseSensor',
}
EMERGENCY = SafetyModel(raise_to_parent=[SAFETY_EVENT])


def to_composition(app: Application) -> CompositeModel:
    """The composition model of a checked application (robot URDFs resolved to absolute paths)."""
    program = app.program
    robots = {r.name: r for r in program.robots}
    drivers = [_driver(d, robots[d.robot], app.rate) for d in app.drivers]
    sensors = [EntityModel(name=f'Sensor_{s.object}', kind=KINDS['pose'],
                           parameters={'object': s.object, 'topic': s.topic}) for s in app.sensors]
    connections = []
    for d in app.drivers:
        connections += [_connect(f'Driver_{d.robot}.joint_state', f'{program.name}.joint_state_{d.robot}'),
                        _connect(f'{program.name}.command', f'Driver_{d.robot}.command')]
    connections += [_connect(f'Sensor_{s.object}.pose', f'{program.name}.pose_{s.object}') for s in app.sensors]
    program_model = _placed(_program(app), app.hosts)
    return CompositeModel(name=app.name, rate=app.rate, entities=[*drivers, *sensors, program_model],
                          connections=connections, monitors=[m for d in app.drivers for m in _watchdogs(d, app.rate)])


def _placed(composite: CompositeModel, hosts: dict[str, str]) -> CompositeModel:
    """``composite`` and the composites inside it on the hosts ``hosts`` names them on."""
    entities = [_placed(e, hosts) if isinstance(e, CompositeModel) else e for e in composite.entities]
    return composite.model_copy(update={'entities': entities, 'host': hosts.get(composite.name, composite.host)})


#: How long a Driver may take to report its first joint state once the application runs.
DRIVER_GRACE = 5.0


def _watchdogs(driver: Driver, rate: float) -> list[MonitorModel]:
    """A silent driver or non-finite joint positions put the application in Safety (its Driver
    then commands zero velocity)."""
    watch = f'Driver_{driver.robot}.joint_state'
    return [
        MonitorModel.model_validate({'name': f'Driver_{driver.robot}_silent', 'watch': watch, 'condition': 'stale',
                                     'timeout': driver.silent_after or max(0.25, 20.0 / rate), 'grace': DRIVER_GRACE,
                                     'event': SAFETY_EVENT}),
        MonitorModel(name=f'Driver_{driver.robot}_nonfinite', watch=watch, field='position',
                     condition='nonfinite', event=SAFETY_EVENT),
    ]


def _connect(source: str, target: str) -> ConnectionModel:
    return ConnectionModel.model_validate({'from': source, 'to': target})


def _placement(item) -> dict[str, list[float]]:
    return {'xyz': list(item.xyz), 'rpy': list(item.rpy)}


# -- Application level ----------------------------------------------------------------------------

def _driver(driver: Driver, robot, rate: float) -> EntityModel:
    """The Driver's entity: its kind's, with the parameters its kind gives it."""
    kind = driver.driver
    return EntityModel(name=f'Driver_{driver.robot}', kind=kind.entity,
                       parameters=kind.parameters(driver, driven_robot(robot, rate)))


# -- Constraint-based program -----------------------------------------------------------------------

def _program(app: Application) -> CompositeModel:
    program = app.program
    tasks = program.tasks
    robot_entities = [EntityModel(name=f'Robot_{r.name}', kind=KINDS['robot'],
                                  parameters={'robot': r.name, 'urdf': r.urdf, 'base': r.base})
                      for r in program.robots]
    connections = [_connect(f'Robot_{r.name}.joint_state', f'Scene.joint_state_{r.name}') for r in program.robots]
    for task in tasks:
        connections += _task_connections(task)
    connections.append(_connect('Scene.joint_state', 'Solver.joint_state'))
    exports = {f'joint_state_{r.name}': f'Robot_{r.name}.measured' for r in program.robots}
    exports |= {f'pose_{s.object}': f'Scene.pose_{s.object}' for s in app.sensors}
    exports['command'] = 'Solver.command'
    monitor_settings = {name: {target: {'threshold': s.threshold} for target, s in targets.items()
                               if s.threshold is not None}
                        for name, targets in program.configurations.items()}
    monitor_settings = {name: targets for name, targets in monitor_settings.items() if targets}
    return CompositeModel(
        name=program.name,
        entities=[*robot_entities, _scene(app), *(_task(program, t, 1.0 / app.rate) for t in tasks),
                  _solver(app, program.solver)],
        composition_steps={name: _step(app, name, step) for name, step in program.composition.items()},
        inactive=_initially_inactive(program),
        connections=connections,
        exports=exports,
        configurations=monitor_settings,
        configure=[c for c in program.configure if c in monitor_settings],
        monitors=[_monitor(m, enabled=_initially_enabled(program, m.name, m.enabled)) for m in program.monitors],
        running=_running(program),
        safety=EMERGENCY,
        events=app.events,
    )


def _scene(app: Application) -> EntityModel:
    program = app.program
    sensed = {s.object for s in app.sensors}
    robots = {r.name: {'urdf': r.urdf, 'base': r.base, **_placement(r),
                       'frames': {f.name: {'link': f.link, **_placement(f)} for f in r.frames}}
              for r in program.robots}
    objects = {o.name: {**_placement(o), 'frames': {f.name: _placement(f) for f in o.frames},
                        'sensed': o.name in sensed, **({'motion': o.motion.model_dump()} if o.motion else {})}
               for o in program.objects}
    relations = {t.name: {'o1': t.chain['o1'], 'o2': t.chain['o2']}
                 for t in program.every_task if t.kind.reads == 'relation'}
    return EntityModel(name='Scene', kind=KINDS['scene'],
                       parameters={'robots': robots, 'objects': objects, 'relations': relations})


def _task_connections(task: Task) -> list[ConnectionModel]:
    """A Task's connections in the program: its chain's input from the Scene, its rows to the Solver."""
    if task.kind.reads == 'joints':
        into = _connect('Scene.joint_state', f'{task.name}.joint_state')
    else:
        into = _connect(f'Scene.relation_{task.name}', f'{task.name}.relation')
    return [into, _connect(f'{task.name}.rows', 'Solver.rows')]


def _step(app: Application, name: str, step: CompositionStep) -> CompositionStepModel:
    """A composition step of the program composite; a Task's swaps are that Task's step ``name``."""
    return CompositionStepModel(
        add=[_task(app.program, t, 1.0 / app.rate) for t in step.add],
        remove=list(step.remove),
        swap=[_solver(app, step.solver)] if step.solver is not None else [],
        connections=[c for t in step.add for c in _task_connections(t)],
        children=dict.fromkeys(step.swap, name))


def _solver(app: Application, solver: Solver) -> EntityModel:
    joints, limits = joint_limits(app.program.robots)
    return EntityModel(name='Solver', kind=KINDS['solver'], parameters={
        **solver.model_dump(exclude={'joint_weights'}), 'joint_names': joints, **limits,
        'joint_weights': [float(solver.joint_weights.get(j, 1.0)) for j in joints], 'period': 1.0 / app.rate})


def _initially_inactive(program: Program) -> list[str]:
    """Tasks the initial state of the Running sub-FSM leaves off compute nothing before it is
    entered either (no conflicting commands during PreRunning)."""
    fsm = program.running
    initial = fsm.states[fsm.initial].tasks if fsm is not None else None
    return [] if initial is None else [t.name for t in program.tasks if t.name not in initial]


def _initially_enabled(program: Program, name: str, enabled: bool) -> bool:
    """A Monitor the initial state of the Running sub-FSM switches is on only if that state says so
    (it would otherwise watch the Tasks before the Coordinator set them up)."""
    fsm = program.running
    initial = fsm.states[fsm.initial].monitors if fsm is not None else None
    return enabled if initial is None else name in initial


def _monitor(monitor: Monitor, *, enabled: bool) -> MonitorModel:
    target, _, quantity = monitor.watch.partition('.')
    if target == 'Solver' and quantity.split('[')[0] in SOLVER_QUANTITIES:
        watch, field = 'Solver.status', quantity
    elif quantity == 'progress':
        watch, field = f'{target}.progress', 'data'
    else:
        watch, field = f'{target}.state', quantity
    return MonitorModel(name=monitor.name, watch=watch, field=field, condition=monitor.condition,
                        event=monitor.event, enabled=enabled, enable_on=[event(monitor.name, ON)],
                        disable_on=[event(monitor.name, OFF)], **monitor.condition_parameters)


def _running(program: Program) -> RunningModel | None:
    fsm = program.running
    if fsm is None:
        return None
    states = {}
    for name, state in fsm.states.items():
        events = []
        for c in state.configure:
            targets = program.configurations[c]
            if any(s.threshold is not None for s in targets.values()):
                events.append(named(c))  # the program's own Configurator (Monitor thresholds)
            events += [to_child(t, c) for t, s in targets.items() if s.for_task]
        if state.tasks is not None:
            events += [event(t.name, ACTIVATE if t.name in state.tasks else DEACTIVATE) for t in program.every_task]
        if state.monitors is not None:
            events += [event(m.name, ON if m.name in state.monitors else OFF) for m in program.monitors]
        compose = [compose_step(program.name, step) for step in state.compose]
        states[name] = {'raise': compose + events + state.raise_}
    return RunningModel.model_validate({
        'initial': fsm.initial, 'states': states,
        'transitions': [{'from': t.source, 'to': t.target, 'when': t.when} for t in fsm.transitions]})


# -- Task -------------------------------------------------------------------------------------------

def _task(program: Program, task: Task, period: float) -> CompositeModel:
    t = task.name
    equality = task.constraint == 'equality'
    entities: list[EntityModel | CompositeModel] = [
        EntityModel(name='VKC', kind=KINDS['vkc'], parameters=_chain(task)),
        EntityModel(name='CO', kind=KINDS['co'], parameters={'task': t, 'outputs': _outputs(task)}),
    ]
    connections = [_connect('VKC.features', 'CO.features'), _connect('CO.output', 'CC.output'),
                   _connect('CO.output', 'Rows.output'), _connect('CC.control', 'Rows.control')]
    if equality:
        entities.append(_setpoint_generator(task, period))
        connections += [_connect('VKC.features', 'SPG.features'), _connect('SPG.setpoint', 'CC.setpoint')]
    entities += [
        _controller(task, period),
        EntityModel(name='Rows', kind=KINDS['rows'], parameters={
            'task': t, 'priority': task.priority, 'weights': [float(w) for w in task.weights],
            'inequality': not equality}),
    ]
    exports = {'joint_state': 'VKC.joint_state'} if task.kind.reads == 'joints' else {'relation': 'VKC.relation'}
    exports |= {'rows': 'Rows.rows', 'state': 'Rows.state'}
    if equality:
        exports['progress'] = 'SPG.progress'
    configurations = {name: _task_settings(targets[t]) for name, targets in program.configurations.items()
                      if t in targets and targets[t].for_task}
    return CompositeModel(name=t, entities=entities, connections=connections, exports=exports,
                          configurations=configurations,
                          configure=[name for name in program.configure if name in configurations],
                          running=_configuration_switch(t, configurations), safety=EMERGENCY,
                          composition_steps={name: _swap(task, step.swap[t], period)
                                             for name, step in program.composition.items() if t in step.swap})


def _outputs(task: Task) -> list[str]:
    return list(task.outputs or ())


def _setpoint_generator(task: Task, period: float) -> EntityModel:
    return EntityModel(name='SPG', kind=KINDS['spg'],
                       parameters=_setpoint(task, _outputs(task)) | {'tick_period': period})


def _controller(task: Task, period: float) -> EntityModel:
    c = task.controller
    return EntityModel(name='CC', kind=KINDS['cc'], parameters={
        'task': task.name, 'tick_period': period, **c.model_dump(),
        'inequality': task.constraint != 'equality', 'lower': [float(v) for v in task.d_min or [-math.inf]],
        'upper': [float(v) for v in task.d_max or [math.inf]]})


def _swap(task: Task, swap: TaskSwap, period: float) -> CompositionStepModel:
    """A Task's part of a composition step: its controller and setpoint generator replaced."""
    swapped = task.model_copy(update={'controller': swap.controller or task.controller,
                                      'setpoint': swap.setpoint or task.setpoint})
    return CompositionStepModel(swap=[entity for entity, given in (
        (_controller(swapped, period), swap.controller), (_setpoint_generator(swapped, period), swap.setpoint))
        if given is not None])


def _task_settings(settings) -> dict[str, dict[str, Any]]:
    """A Task's part of a named configuration, per entity: gains (CC), weights and priority (Rows)."""
    entities: dict[str, dict[str, Any]] = {}
    if settings.controller is not None:
        entities['CC'] = settings.controller.model_dump(exclude_none=True)
    rows = {'weights': [float(w) for w in settings.weights] if settings.weights is not None else None,
            'priority': settings.priority}
    if any(v is not None for v in rows.values()):
        entities['Rows'] = {k: v for k, v in rows.items() if v is not None}
    return entities


def _chain(task: Task) -> dict[str, Any]:
    """The VKC's parameters: the Task's type and its chain's fields (the task type's model)."""
    return {'task': task.name, 'type': task.type, **task.chain}


def _setpoint(task: Task, outputs: list[str]) -> dict[str, Any]:
    """The SPG's parameters: the Task's setpoint section (the same model), its outputs."""
    params: dict[str, Any] = {'task': task.name, 'outputs': outputs}
    if task.setpoint is None:
        return params | {'kind': 'hold'}
    return params | task.setpoint.model_dump(exclude_none=True)


def _configuration_switch(task: str, configurations: dict[str, Any]) -> RunningModel | None:
    """The Task's Running sub-FSM: on the parent's ``e_<Task>_<configuration>``, enter that state,
    which raises ``e_<configuration>`` in the Task, where its Configurator applies it."""
    if not configurations:
        return None
    states: dict[str, dict[str, list[str]]] = {AS_CONFIGURED: {}} | {name: {'raise': [named(name)]}
                                                                     for name in configurations}
    transitions = [{'from': s, 'to': name, 'when': [to_child(task, name)]}
                   for name in configurations for s in states if s != name]
    return RunningModel.model_validate({'initial': AS_CONFIGURED, 'states': states, 'transitions': transitions})

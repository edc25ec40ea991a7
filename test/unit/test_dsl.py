"""The iTaSC application model (paper §4.2; issue #4 "The application model"): the shipped
applications load and transform into a composition whose every connection passes the Composer's
port-metadata check; broken models are refused before anything starts, with an error naming the
file (the included one where the fault lies) and the path inside it.
"""

from __future__ import annotations

import copy
import subprocess
import sys
from pathlib import Path
from collections import Counter
from typing import Any, Callable

import pytest
import rclpy
import yaml

from itasc_bringup import bootstrap
from itasc_bringup.apps import check_model, load_composition
from itasc_core.communication.ports import check_connection
from itasc_core.composition.loader import ModelError
from itasc_core.composition.model import CompositeModel, walk
from itasc_core.composition.resolve import port_of
from itasc_core.computation.functional_entity import FunctionalEntity

SHIPPED = ('approach_object', 'approach_object_ros_driver', 'mobile_manipulator')


# -- the shipped applications ---------------------------------------------------------------------

def _check_ports(model: CompositeModel) -> None:
    """What the Composers will check: every connection joins ports that agree on their metadata."""
    for path, composite in walk(model):
        namespace = '/'.join(path.split('/')[:-1]) + f'/{composite.name}'
        for connection in composite.connections:
            source, source_name = port_of(composite, namespace, connection.source)
            target, target_name = port_of(composite, namespace, connection.target)
            check_connection(source, target, source_name=source_name, target_name=target_name)
        for monitor in composite.monitors:
            port_of(composite, namespace, monitor.watch)


@pytest.mark.parametrize('app', SHIPPED)
def test_shipped_application_loads_and_every_connection_agrees_on_port_metadata(app):
    assert check_model(app) is None
    _check_ports(load_composition(app))


def test_the_ports_of_a_program_of_many_tasks_are_resolved_validating_each_entity_once(tmp_path, monkeypatch):
    """The Scene and the Solver, which every Task connects to, have parameters that grow with the
    Tasks: validated once per connection, loading and deploying a program took time growing with
    the square of its Tasks (issue #9: bring-up against the number of Tasks)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / 'bench'))
    from scaling import application
    model = tmp_path / 'many.yaml'
    model.write_text(yaml.safe_dump(application(tasks=12)))
    validated: Counter[int] = Counter()
    validate = FunctionalEntity.parameters_of.__func__

    def counted(cls, values):
        validated[id(values)] += 1
        return validate(cls, values)
    monkeypatch.setattr(FunctionalEntity, 'parameters_of', classmethod(counted))
    composition = load_composition(str(model))  # checks every connection
    _check_ports(composition)  # as the Composers do
    _check_ports(composition)  # as a re-composition's checks do
    assert validated and max(validated.values()) <= 2, validated.most_common(3)  # the model's check, then its ports


def test_approach_object_has_the_three_levels_of_composition():
    app = load_composition('approach_object')
    assert [e.name for e in app.entities] == ['Driver_panda', 'itasc']
    program = app.entity('itasc')
    assert isinstance(program, CompositeModel)
    assert [e.name for e in program.entities] == ['Robot_panda', 'Scene', 'ApproachObject', 'AvoidObstacle',
                                                  'Retreat', 'Solver']
    task = program.entity('ApproachObject')
    assert [e.name for e in task.entities] == ['VKC', 'CO', 'SPG', 'CC', 'Rows']
    assert set(task.exports) == {'relation', 'rows', 'state', 'progress'}
    assert set(program.entity('AvoidObstacle').exports) == {'relation', 'rows', 'state'}  # no setpoint
    # the program's Running sub-FSM activates Tasks and switches Monitors
    states = program.running.states
    assert {'e_Retreat_deactivate', 'e_ApproachObject_activate', 'e_arrived_on'} <= set(states['approach'].raise_)
    monitor = next(m for m in program.monitors if m.event == 'e_max_pos_tracking_error_exc')
    assert (monitor.watch, monitor.field, monitor.enabled) == ('ApproachObject.state', 'error_norm', True)
    assert not next(m for m in program.monitors if m.name == 'converged').enabled
    assert app.rate == 100


def _running_fsm(model: CompositeModel, *, root: bool):
    """The composite's life-cycle FSM brought to Running, and the events it raises from then on."""
    from itasc_core.composition.composer import running_spec
    from itasc_core.coordination.lifecycle import LifecycleFsm

    raised: list[str] = []
    fsm = LifecycleFsm(composite=model.name, children=[c.name for c in model.children], is_root=root,
                       raise_event=lambda name, to_parent: raised.append(name), running=running_spec(model))
    c, kids = model.name, [k.name for k in model.children]
    for step in (['configure', 'deployed', 'entities_configured'], ['connected', 'start', 'scheduler_initialized'],
                 ['run', 'scheduler_activated']):
        for event in [f'e_{c}_{s}' for s in step] + [f'e_{k}_{n}' for k in kids for n in
                                                     ('configured', 'started', 'running')]:
            fsm.process(event)
    assert fsm.state.startswith('Active.Run.Running'), fsm.state
    raised.clear()
    return fsm, raised


def test_a_configuration_of_the_running_sub_fsm_reaches_the_task_it_configures():
    """Fig. 3 as pure event processing: the program's hold state commands high_accuracy_control to
    ApproachObject alone; that Task's Coordinator enters its switch state and raises the event its
    own Configurator applies, with the Task's gains."""
    program = load_composition('approach_object').entity('itasc')
    task = program.entity('ApproachObject')
    fsm, raised = _running_fsm(program, root=False)
    fsm.process('e_ApproachObject_arrived')  # approach -> hold
    assert fsm.running_substate == 'hold'
    commands = [e for e in raised if 'accuracy' in e]
    assert commands == ['e_ApproachObject_high_accuracy_control']  # addressed to the one Task concerned
    task_fsm, task_raised = _running_fsm(task, root=False)
    for command in commands:
        task_fsm.process(command)
    assert task_fsm.running_substate == 'high_accuracy_control'
    assert task_raised == ['e_high_accuracy_control']
    assert task.configurations['high_accuracy_control'] == {'CC': {'kp': 4.0, 'ki': 2.0}}
    for other in ('AvoidObstacle', 'Retreat'):  # no other Task reacts to it
        other_fsm, other_raised = _running_fsm(program.entity(other), root=False)
        for command in commands:
            other_fsm.process(command)
        assert other_raised == [] and other_fsm.state == 'Active.Run.Running'


def test_the_ros_driver_application_runs_the_same_program_with_another_driver():
    simulated, ros = load_composition('approach_object'), load_composition('approach_object_ros_driver')
    assert simulated.entity('itasc') == ros.entity('itasc')
    driver = ros.entity('Driver_panda')
    assert driver.kind.endswith(':Ros2ControlAdapter')
    assert driver.parameters['command_topic'] == '/velocity_controller/commands'


def test_mobile_manipulator_has_base_joints_weighted_for_the_solver():
    solver = load_composition('mobile_manipulator').entity('itasc').entity('Solver')
    joints = solver.parameters['joint_names']
    assert joints[:3] == ['mobile_base_x', 'mobile_base_y', 'mobile_base_theta'] and len(joints) == 10
    assert solver.parameters['joint_weights'][:3] == [0.2, 0.2, 0.5]


def test_a_pose_sensor_feeds_the_scene_of_a_moving_object(tmp_path):
    model = copy.deepcopy(BASE)
    model['application']['sensors'] = [{'object': 'target', 'topic': '/target_pose'}]
    app = load_composition(_write(tmp_path, 'app.yaml', model))
    _check_ports(app)
    assert app.entity('Sensor_target').parameters == {'object': 'target', 'topic': '/target_pose'}
    assert app.entity('itasc').exports['pose_target'] == 'Scene.pose_target'


def test_a_model_path_and_a_generic_composition_model_are_accepted(repo_root):
    assert check_model(repo_root / 'config' / 'apps' / 'approach_object.yaml') is None
    assert isinstance(load_composition('pattern_demo'), CompositeModel)


def test_an_unknown_application_name_is_a_model_error():
    err = check_model('no_such_app')
    assert isinstance(err, ModelError) and 'approach_object' in err.message


# -- broken models ----------------------------------------------------------------------------------

BASE = yaml.safe_load("""
application:
  name: app
  rate: 100
  program:
    robots:
      - name: panda
        urdf: panda.urdf
        frames: [{name: tcp, link: panda_hand_tcp}]
    objects:
      - {name: target, xyz: [0.5, 0.1, 0.3], frames: [{name: grasp, rpy: [3.14159, 0, 0]}]}
      - {name: obstacle, xyz: [0.4, 0, 0.5]}
    tasks:
      - name: Approach
        type: cartesian
        o1: target/grasp
        o2: panda/tcp
        controller: {kind: p, kp: 2.0}
        setpoint: {kind: minimum_jerk, pose: {xyz: [0, 0, 0]}, duration: 2.0}
      - {name: Avoid, type: distance, o1: obstacle, o2: panda/panda_hand, constraint: inequality, d_min: 0.1}
      - {name: Posture, type: joint, joints: [panda_joint1, panda_joint2], priority: 1}
    configurations:
      precise: {Approach: {controller: {kp: 5.0}}, arrived: {threshold: 0.99}}
    monitors:
      - {name: arrived, watch: Approach.progress, condition: above, threshold: 0.999, event: e_arrived}
    running:
      initial: approach
      states:
        approach: {tasks: [Approach, Avoid, Posture], monitors: [arrived]}
        hold: {configure: [precise]}
      transitions:
        - {from: approach, to: hold, when: e_arrived}
  drivers:
    - {robot: panda, kind: simulated, initial: {panda_joint4: -2.0}}
""")

P = 'application.program.'


def _set(path: str, value: Any) -> Callable[[dict], None]:
    """A mutation setting (or, with value DELETE, deleting) ``a.b[1].c`` in the model."""
    def mutate(model: dict) -> None:
        keys = [int(k) if k.isdigit() else k for k in path.replace('[', '.').replace(']', '').split('.')]
        node = model
        for key in keys[:-1]:
            node = node[key]
        if value is DELETE:
            del node[keys[-1]]
        else:
            node[keys[-1]] = value
    return mutate


DELETE = object()
ROS_DRIVER = {'robot': 'panda', 'kind': 'ros2_control', 'controller': 'velocity_controller',
              'joints': [f'panda_joint{i}' for i in range(1, 7)]}

#: (id, mutation, expected path in the main file, words of the message)
BROKEN = [
    ('rate not a number', _set('application.rate', 'fast'), 'application.rate', 'valid number'),
    ('negative rate', _set('application.rate', -10), 'application.rate', 'greater than or equal to 0.01'),
    ('negative gain', _set(P + 'tasks[0].controller.kp', -1.0), P + 'tasks[0].controller.kp',
     'greater than or equal to 0'),
    ('gain of wrong type', _set(P + 'tasks[0].controller.kp', [1]), P + 'tasks[0].controller.kp', 'valid number'),
    ('missing task type', _set(P + 'tasks[0].type', DELETE), P + 'tasks[0].type', 'required field is missing'),
    ('missing urdf', _set(P + 'robots[0].urdf', DELETE), P + 'robots[0].urdf', 'required field is missing'),
    ('missing program', _set('application.program', DELETE), 'application.program', 'required field is missing'),
    ('unknown field', _set(P + 'tasks[0].gain', 3), P + 'tasks[0].gain', 'unknown field'),
    ('unknown task type', _set(P + 'tasks[0].type', 'spherical'), P + 'tasks[0].type', "'cartesian'"),
    ('task name with a space', _set(P + 'tasks[0].name', 'Approach Object'), P + 'tasks[0].name', 'pattern'),
    ('limit of an unknown joint', _set(P + 'robots[0].limits', {'panda_joint9': {'velocity': 1.0}}),
     P + 'robots[0].limits.panda_joint9', "no joint 'panda_joint9'"),
    ('negative velocity limit', _set(P + 'robots[0].limits', {'panda_joint1': {'velocity': -1.0}}),
     P + 'robots[0].limits.panda_joint1.velocity', 'greater than 0'),
    ('lower limit above upper', _set(P + 'robots[0].limits', {'panda_joint1': {'lower': 1.0, 'upper': 0.5}}),
     P + 'robots[0].limits.panda_joint1', 'must be below upper'),
    ('unknown link', _set(P + 'robots[0].frames[0].link', 'panda_palm'), P + 'robots[0].frames[0].link',
     "no link 'panda_palm'"),
    ('unknown object frame', _set(P + 'tasks[0].o1', 'target/handle'), P + 'tasks[0].o1',
     "unknown frame 'target/handle'"),
    ('unknown robot frame', _set(P + 'tasks[1].o2', 'panda/elbow'), P + 'tasks[1].o2', "unknown frame 'panda/elbow'"),
    ('unknown owner of a frame', _set(P + 'tasks[0].o2', 'ur5/tcp'), P + 'tasks[0].o2', "unknown frame 'ur5/tcp'"),
    ('same frame twice', _set(P + 'tasks[0].o2', 'target/grasp'), P + 'tasks[0].o2', 'different frames'),
    ('unknown joint of a joint task', _set(P + 'tasks[2].joints[1]', 'panda_joint9'), P + 'tasks[2].joints[1]',
     "unknown joint 'panda_joint9'"),
    ('event nobody raises', _set(P + 'running.transitions[0].when', 'e_grasped'), P + 'running.transitions[0].when[0]',
     "'e_grasped' is raised by nobody"),
    ('unknown configuration in a state', _set(P + 'running.states.hold.configure', ['fast']),
     P + 'running.states.hold.configure[0]', "unknown configuration 'fast'"),
    ('unknown initial configuration', _set(P + 'configure', ['fast']), P + 'configure[0]',
     "unknown configuration 'fast'"),
    ('unknown task in a state', _set(P + 'running.states.approach.tasks', ['Approach', 'Dodge']),
     P + 'running.states.approach.tasks[1]', "unknown task 'Dodge'"),
    ('unknown monitor in a state', _set(P + 'running.states.hold.monitors', ['watchdog']),
     P + 'running.states.hold.monitors[0]', "unknown monitor 'watchdog'"),
    ('unknown state in a transition', _set(P + 'running.transitions[0].to', 'grasp'), P + 'running.transitions[0].to',
     "unknown state 'grasp'"),
    ('unknown initial state', _set(P + 'running.initial', 'start'), P + 'running.initial', "unknown state 'start'"),
    ('duplicate task names', _set(P + 'tasks[1].name', 'Approach'), P + 'tasks[1].name',
     "duplicate task name 'Approach'"),
    ('robot and object of one name', _set(P + 'objects[1].name', 'panda'), P + 'objects[1].name',
     'duplicate robot or object'),
    ('position of two values', _set(P + 'objects[0].xyz', [0.5, 0.1]), P + 'objects[0].xyz',
     'expected at least 3 values, got 2 ([0.5, 0.1])'),
    ('duplicate object frames', _set(P + 'objects[0].frames', [{'name': 'grasp'}, {'name': 'grasp'}]),
     P + 'objects[0].frames[1].name', "duplicate frame"),
    ('task named like an entity', _set(P + 'tasks[2].name', 'Solver'), P + 'tasks[2].name', "'Solver' is reserved"),
    ('monitor named like a task', _set(P + 'monitors[0].name', 'Avoid'), P + 'monitors[0].name', "'Avoid' is reserved"),
    ('negative weight', _set(P + 'tasks[0].weights', -1), P + 'tasks[0].weights', 'weights must be > 0'),
    ('weights of the wrong size', _set(P + 'tasks[0].weights', [1, 1]), P + 'tasks[0]', 'one per output (6)'),
    ('inequality without bounds', _set(P + 'tasks[1].d_min', DELETE), P + 'tasks[1]', 'needs d_min'),
    ('outputs the chain has not', _set(P + 'tasks[0].outputs', ['x', 'q']), P + 'tasks[0]', "outputs ['q']"),
    ('negative setpoint duration', _set(P + 'tasks[0].setpoint.duration', -2), P + 'tasks[0].setpoint.duration',
     'greater than or equal to 0'),
    ('setpoint of the wrong size', _set(P + 'tasks[0].setpoint', {'kind': 'fixed', 'value': [0, 0]}), P + 'tasks[0]',
     'setpoint value has 2 values for 6 outputs'),
    ('urdf not found', _set(P + 'robots[0].urdf', 'kuka.urdf'), P + 'robots[0].urdf', "URDF 'kuka.urdf' not found"),
    ('monitor of an unknown task', _set(P + 'monitors[0].watch', 'Grasp.error_norm'), P + 'monitors[0].watch',
     "unknown task 'Grasp'"),
    ('monitor of an unknown quantity', _set(P + 'monitors[0].watch', 'Approach.force'), P + 'monitors[0].watch',
     "a task has no 'force'"),
    ('monitor event without e_', _set(P + 'monitors[0].event', 'arrived'), P + 'monitors[0].event', 'pattern'),
    ('configuration of an unknown task', _set(P + 'configurations.precise', {'Grasp': {'controller': {'kp': 1}}}),
     P + 'configurations.precise.Grasp', "unknown task or monitor 'Grasp'"),
    ('negative gain in a configuration', _set(P + 'configurations.precise.Approach.controller.kp', -5),
     P + 'configurations.precise.Approach.controller.kp', 'greater than or equal to 0'),
    ('gain the controller has not', _set(P + 'tasks[0].controller', {'kind': 'p', 'kp': 2.0, 'ki': 0.5}),
     P + 'tasks[0].controller.ki', 'unknown field'),
    ('unknown controller', _set(P + 'tasks[0].controller', {'kind': 'lqr'}), P + 'tasks[0].controller.kind',
     "unknown constraint controller 'lqr'"),
    ('configuration of a gain the controller has not',
     _set(P + 'configurations.precise.Approach.controller', {'ki': 0.5}),
     P + 'configurations.precise.Approach.controller.ki', "a p controller, without ki"),
    ('no driver at all', _set('application.drivers', []), 'application.drivers', 'at least 1 item'),
    ('driver of an unknown robot', _set('application.drivers[0].robot', 'kuka'), 'application.drivers[0].robot',
     "unknown robot 'kuka'"),
    ('driver with an unknown joint', _set('application.drivers[0].initial', {'panda_joint9': 0.0}),
     'application.drivers[0].initial.panda_joint9', "no joint 'panda_joint9'"),
    ('ros driver missing a joint', _set('application.drivers', [ROS_DRIVER]), 'application.drivers[0].joints',
     "missing: ['panda_joint7']"),
    ('ros driver without its controller',
     _set('application.drivers', [{k: v for k, v in ROS_DRIVER.items() if k != 'controller'}]),
     'application.drivers[0].controller', 'required field is missing'),
    ('simulated driver with a controller', _set('application.drivers[0].controller', 'velocity_controller'),
     'application.drivers[0].controller', 'unknown field'),
    ('unknown driver', _set('application.drivers[0].kind', 'franka_hw'), 'application.drivers[0].kind',
     "unknown driver 'franka_hw'"),
    ('sensor of an unknown object', _set('application.sensors', [{'object': 'cup', 'topic': '/cup_pose'}]),
     'application.sensors[0].object', "unknown object 'cup'"),
    ('unavailable QP backend', _set(P + 'solver', {'kind': 'qp', 'backend': 'gurobi'}), P + 'solver.backend',
     "'gurobi' is not available"),
    ('solver weight of an unknown joint', _set(P + 'solver', {'joint_weights': {'base_x': 0.1}}),
     P + 'solver.joint_weights.base_x', "unknown joint 'base_x'"),
]


def _write(directory: Path, name: str, model: Any) -> Path:
    path = directory / name
    path.write_text(model if isinstance(model, str) else yaml.safe_dump(model, sort_keys=False))
    return path


@pytest.mark.parametrize('mutate, path, words', [case[1:] for case in BROKEN], ids=[case[0] for case in BROKEN])
def test_broken_model_names_the_file_and_the_field(tmp_path, capsys, mutate, path, words):
    model = copy.deepcopy(BASE)
    mutate(model)
    file = _write(tmp_path, 'app.yaml', model)
    err = check_model(file)
    assert isinstance(err, ModelError), 'the broken model was accepted'
    assert (err.file, err.path) == (str(file), path), str(err)
    assert words in err.message, str(err)
    # the bootstrap refuses it the same way: exit 2, the error on stderr, nothing started
    with pytest.raises(SystemExit) as exit_info:
        bootstrap.main([str(file)])
    assert exit_info.value.code == 2
    assert capsys.readouterr().err == f'error: {err}\n'
    assert not rclpy.ok()


def test_the_base_of_the_broken_models_is_valid(tmp_path):
    assert check_model(_write(tmp_path, 'app.yaml', BASE)) is None


def test_error_inside_an_included_task_names_the_included_file(tmp_path):
    model = copy.deepcopy(BASE)
    task = model['application']['program']['tasks'][0]
    task['controller']['kp'] = 'high'
    (tmp_path / 'tasks').mkdir()
    included = _write(tmp_path / 'tasks', 'approach.yaml', task)
    model['application']['program']['tasks'][0] = {'include': 'tasks/approach.yaml'}
    err = check_model(_write(tmp_path, 'app.yaml', model))
    assert (err.file, err.path) == (str(included), 'controller.kp'), str(err)


def test_unknown_link_in_an_included_robot_names_the_robot_file(tmp_path):
    model = copy.deepcopy(BASE)
    robot = model['application']['program']['robots'][0]
    robot['frames'][0]['link'] = 'gripper'
    _write(tmp_path, 'robot.yaml', robot)
    model['application']['program']['robots'][0] = {'include': 'robot.yaml'}
    err = check_model(_write(tmp_path, 'app.yaml', model))
    assert (err.file, err.path) == (str(tmp_path / 'robot.yaml'), 'frames[0].link'), str(err)
    assert "no link 'gripper'" in err.message


def test_dangling_file_reference(tmp_path):
    model = copy.deepcopy(BASE)
    model['application']['program']['tasks'][1] = {'include': 'tasks/avoid.yaml'}
    file = _write(tmp_path, 'app.yaml', model)
    err = check_model(file)
    assert (err.file, err.path) == (str(file), P + 'tasks[1].include') and 'cannot be read' in err.message, str(err)


def test_include_cycle(tmp_path):
    _write(tmp_path, 'a.yaml', {'name': 'panda', 'urdf': 'panda.urdf', 'frames': {'include': 'app.yaml'}})
    model = copy.deepcopy(BASE)
    model['application']['program']['robots'][0] = {'include': 'a.yaml'}
    err = check_model(_write(tmp_path, 'app.yaml', model))
    assert 'include cycle' in err.message, str(err)


def test_yaml_syntax_error_names_line_and_column(tmp_path):
    file = _write(tmp_path, 'app.yaml', 'application:\n  name: app\n  rate: [100\n')
    err = check_model(file)
    assert err.file == str(file) and err.path.startswith('line ') and 'YAML syntax error' in err.message, str(err)


def test_yaml_syntax_error_in_an_included_file(tmp_path):
    _write(tmp_path, 'task.yaml', 'name: Approach\ntype: cartesian\n  o1: x\n')
    model = copy.deepcopy(BASE)
    model['application']['program']['tasks'][0] = {'include': 'task.yaml'}
    err = check_model(_write(tmp_path, 'app.yaml', model))
    assert Path(err.file).name == 'task.yaml' and 'YAML syntax error' in err.message, str(err)


def test_unknown_top_level_key(tmp_path):
    file = _write(tmp_path, 'app.yaml', {'aplication': BASE['application']})
    err = check_model(file)
    assert err.file == str(file) and "'application'" in err.message, str(err)


def test_extra_top_level_key(tmp_path):
    file = _write(tmp_path, 'app.yaml', {**BASE, 'extra': 1})
    err = check_model(file)
    assert (err.file, err.path) == (str(file), 'extra'), str(err)


def test_bootstrap_refuses_a_broken_model_with_exit_2_and_no_traceback(tmp_path):
    model = copy.deepcopy(BASE)
    model['application']['program']['tasks'][0]['controller']['kp'] = -1
    file = _write(tmp_path, 'app.yaml', model)
    result = subprocess.run([sys.executable, '-m', 'itasc_bringup.bootstrap', str(file)], capture_output=True,
                            text=True, timeout=60)
    assert result.returncode == 2, result.stderr
    assert 'Traceback' not in result.stderr + result.stdout
    assert f'{file}: {P}tasks[0].controller.kp' in result.stderr


def test_joint_limits_in_the_model_override_the_urdfs(tmp_path):
    model = copy.deepcopy(BASE)
    model['application']['program']['robots'][0]['limits'] = {'panda_joint1': {'lower': -0.5, 'velocity': 0.3}}
    composition = load_composition(str(_write(tmp_path, 'app.yaml', model)))
    solver = next(e for e in composition.entity('itasc').entities if e.name == 'Solver').parameters
    i = solver['joint_names'].index('panda_joint1')
    assert (solver['lower'][i], solver['velocity_limit'][i]) == (-0.5, 0.3)
    assert solver['upper'][i] == pytest.approx(2.8973)  # from the URDF


def test_a_moving_object_follows_its_trajectory_in_the_scene(tmp_path):
    """The Scene the model builds (its SceneEntity, from the parameters the transform gives it) moves
    the object along the trajectory of the model."""
    from itasc_core.entity import CompositeContext
    from itasc_core.itasc.entities import SceneEntity

    model = copy.deepcopy(BASE)
    target = model['application']['program']['objects'][0]
    target['motion'] = {'amplitude': [0.0, 0.1, 0.0], 'period': 4.0}
    scene_model = next(e for e in load_composition(str(_write(tmp_path, 'app.yaml', model))).entity('itasc').entities
                       if e.name == 'Scene')
    rclpy.init()
    try:
        entity = SceneEntity('Scene', composite=CompositeContext(name='itasc', namespace='/app/itasc'),
                             parameters=scene_model.parameters)
        try:
            scene = entity.scene
            for t, dy in ((0.0, 0.0), (1.0, 0.1), (2.0, 0.0), (3.0, -0.1)):  # quarter periods
                scene.update(t)
                y = scene.pose('target').translation[1]
                assert y == pytest.approx(target['xyz'][1] + dy, abs=1e-9), (t, y)
        finally:
            entity.destroy_node()
    finally:
        rclpy.try_shutdown()

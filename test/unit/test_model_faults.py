"""Bad models are refused cleanly and fast (issue #8, items 1 and 2; README "Faults and bad input /
Bad models"): every fault of a model, whatever its kind, is a ModelError naming the file, the path
inside it and the value, found within bounded time before anything starts; the bootstrap exits 2,
without a traceback and without creating a DDS participant. Models are data: entity kinds come from
the registry only, includes stay inside the model's folders.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import sys
import time
import types
import typing
from pathlib import Path
from typing import Any

import annotated_types
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pydantic import BaseModel

from itasc_bringup.apps import load_composition
from itasc_bringup.model import transform
from itasc_bringup.model.schema import Application
from itasc_core.composition.loader import MAX_BYTES, MAX_DEPTH, MAX_VALUES, ModelError, format_loc
from itasc_core.composition.registry import ENTRY_POINTS, known_kind, resolve_kind
from itasc_core.computation.library import SineSource
from model_files import edit_yaml
from processes import Spawned

REPO = Path(__file__).resolve().parents[2]
#: The CPU time a refusal may take in-process (the bootstrap's bound, 5 s, includes starting
#: Python). CPU time of this process, not wall time: other processes loading the machine (a parallel
#: test run) must not fail it, a model that blows up still does.
BOUND = 3.0


def refused(app: Path) -> ModelError:
    start = time.process_time()
    with pytest.raises(ModelError) as info:
        load_composition(str(app))
    spent = time.process_time() - start
    assert spent < BOUND, f'refused only after {spent:.1f} s of CPU: {info.value}'
    return info.value


def _app(config: Path) -> Path:
    return config / 'apps' / 'approach_object.yaml'


def _program(config: Path) -> Path:
    return config / 'programs' / 'approach_object.yaml'


# -- the cases of issue #8, each refused today by nothing or by a traceback -----------------------------

def test_a_monitor_index_beyond_the_watched_vector_is_refused(config):
    edit_yaml(_program(config), lambda p: p['monitors'][0].update(watch='ApproachObject.error[9]'))
    err = refused(_app(config))
    assert (err.file, err.path) == (str(_program(config)), 'monitors[0].watch'), str(err)
    assert 'ApproachObject.error[9]' in err.message and '6 values' in err.message, str(err)


def test_an_index_of_a_single_number_is_refused(config):
    edit_yaml(_program(config), lambda p: p['monitors'][0].update(watch='ApproachObject.error_norm[0]'))
    err = refused(_app(config))
    assert (err.file, err.path) == (str(_program(config)), 'monitors[0].watch'), str(err)


@pytest.mark.parametrize('value', [math.nan, math.inf, -math.inf])
def test_a_non_finite_task_weight_is_refused(config, value):
    task = config / 'tasks' / 'approach_object.yaml'
    edit_yaml(task, lambda t: t['weights'].__setitem__(1, value))
    err = refused(_app(config))
    assert (err.file, err.path) == (str(task), 'weights[1]'), str(err)
    assert str(value) in err.message and 'finite' in err.message, str(err)


@pytest.mark.parametrize('value', ['inf', '-Infinity', 'nan', '1e400'])
def test_a_non_finite_number_written_as_a_string_is_refused(config, value):
    """Pydantic reads ``'inf'`` as a number where one is expected: the rate went through as inf (a
    traceback when the Timer was made), a setpoint's duration as inf (a Task that never moves),
    a driver's ``silent_after`` as inf (its watchdog off)."""
    edit_yaml(_app(config), lambda a: a['application'].update(rate=value))
    err = refused(_app(config))
    assert (err.file, err.path, err.message) == (str(_app(config)), 'application.rate',
                                                 f'{value!r} is not a finite number'), str(err)


@pytest.mark.parametrize('rate', [1e-9, 1e6, '1e308'])
def test_a_rate_no_timer_can_keep_is_refused(config, rate):
    """0.01 Hz to 100 kHz: 1e308 overflowed the Timer's next tick (a traceback), 1e-9 ran with no
    tick at all and exited 0."""
    edit_yaml(_app(config), lambda a: a['application'].update(rate=rate))
    err = refused(_app(config))
    assert (err.file, err.path) == (str(_app(config)), 'application.rate'), str(err)
    assert 'greater than or equal to 0.01' in err.message or 'less than or equal to 100000' in err.message, str(err)


@pytest.mark.parametrize('app, edit, path, message', [
    ('approach_object_ros_driver', lambda a: a['application']['drivers'][0].update(joint_states='bad topic!'),
     'application.drivers[0].joint_states', "'bad topic!' is not a ROS topic name: topic name must not contain "
     "characters other than alphanumerics, '_', '~', '{', or '}'"),
    ('approach_object_ros_driver', lambda a: a['application']['drivers'][0].update(controller='a//b'),
     'application.drivers[0].controller', "'a//b' is not a ROS topic name: topic name must not contain repeated '/'"),
    ('approach_object_ros_driver', lambda a: a['application']['drivers'][0].update(command_topic='/x/1y'),
     'application.drivers[0].command_topic', "'/x/1y' is not a ROS topic name: topic name token must not start "
     "with a number"),
    ('approach_object', lambda a: a['application'].update(sensors=[{'object': 'target', 'topic': '/target/pose/'}]),
     'application.sensors[0].topic', "'/target/pose/' is not a ROS topic name: topic name must not end with a "
     "forward slash"),
])
def test_a_topic_name_ros_would_refuse_is_refused_with_the_model(config, app, edit, path, message):
    """Before, the model passed and the node that was to use the topic failed while the
    application deployed its entities: an rclpy traceback, Safety, exit 2 after the start."""
    model = config / 'apps' / f'{app}.yaml'
    edit_yaml(model, edit)
    err = refused(model)
    assert (err.file, err.path, err.message) == (str(model), path, message), str(err)


@pytest.mark.parametrize('app', ['approach_object', 'approach_object_ros_driver'])
def test_a_limit_that_crosses_the_urdfs_other_limit_is_refused_where_it_is_given(config, app):
    """A model's ``lower`` above the URDF's upper: with a ros2_control driver the model was taken
    (the Solver planned on lower > upper); with a simulated one the error blamed the initial
    positions in another file."""
    edit_yaml(config / 'robots' / 'panda.yaml', lambda r: r.update(limits={'panda_joint1': {'lower': 5.0}}))
    err = refused(config / 'apps' / f'{app}.yaml')
    assert (err.file, err.path, err.message) == (
        str(config / 'robots' / 'panda.yaml'), 'limits.panda_joint1',
        "lower 5 is above upper 2.8973 (the URDF's: [-2.8973, 2.8973])"), str(err)


def test_a_urdf_whose_limits_are_crossed_is_refused(config):
    """Before, the joint was taken as unlimited and the application ran."""
    urdf = config / 'robots' / 'panda.urdf'
    text = urdf.read_text()
    at = text.index('<limit', text.index('name="panda_joint1"'))
    crossed = text[at:].replace('lower="-2.8973" upper="2.8973"', 'lower="2.8973" upper="-2.8973"', 1)
    urdf.write_text(text[:at] + crossed)
    err = refused(_app(config))
    assert (err.file, err.path, err.message) == (
        str(config / 'robots' / 'panda.yaml'), 'urdf',
        "URDF 'panda.urdf': the lower limit of panda_joint1 is above its upper limit"), str(err)


def _rename_configuration(program: dict, old: str, new: str) -> None:
    program['configurations'][new] = program['configurations'].pop(old)
    for state in program['running']['states'].values():
        state['configure'] = [new if c == old else c for c in state.get('configure', [])]


@pytest.mark.parametrize('edit, path, message', [
    (lambda p: p['running']['states']['hold'].update({'raise': ['e_itasc_stop']}), 'running.states.hold.raise[0]',
     "'e_itasc_stop' is an event of the life cycle of composite 'itasc': the runtime raises it, a model does not"),
    (lambda p: p['monitors'][0].update(event='e_AvoidObstacle_deactivate'), 'monitors[0].event',
     "'e_AvoidObstacle_deactivate' is an event of the life cycle of composite 'AvoidObstacle': the runtime raises "
     "it, a model does not"),
    (lambda p: p['monitors'][0].update(event='e_itasc_configure_entities'), 'monitors[0].event',
     "'e_itasc_configure_entities' is an event of the life cycle of composite 'itasc': the runtime raises it, a "
     "model does not"),
    (lambda p: _rename_configuration(p, 'high_accuracy_control', 'stop'), 'configurations.stop',
     "'stop' is reserved (a word of the life cycle, or the configuration a Task starts in): choose another "
     "configuration name"),
    (lambda p: _rename_configuration(p, 'high_accuracy_control', 'as_configured'), 'configurations.as_configured',
     "'as_configured' is reserved (a word of the life cycle, or the configuration a Task starts in): choose "
     "another configuration name"),
    (lambda p: p['monitors'][1].update(name='coordinator'), 'monitors[1].name',
     "'coordinator' is reserved: choose another monitor name"),
])
def test_a_model_does_not_speak_the_life_cycle_or_take_the_composites_own_names(config, edit, path, message):
    """A state raising ``e_itasc_stop`` stopped the program from inside (the run hung until its
    stop timed out, exit 1); a configuration named ``stop`` or ``activate`` is commanded to a Task
    as its life-cycle command (``activate`` switched the gains when the Task was activated, not
    on the Monitor's event); a Monitor named ``coordinator`` shared the Coordinator's node name
    (events were reported lost). Each ran; now the model is refused naming the field."""
    edit_yaml(_program(config), edit)
    err = refused(_app(config))
    assert (err.file, err.path, err.message) == (str(_program(config)), path, message), str(err)


@pytest.mark.parametrize('task, setpoint, message', [
    ('retreat', {'kind': 'minimum_jerk', 'value': [0, 0, -0.15], 'duration': 2.0, 'max_velocity': [1, 1]},
     "setpoint max_velocity has 2 values for 3 outputs ['x', 'y', 'z']"),
    ('retreat', {'kind': 'trapezoidal', 'value': [0, 0, -0.15], 'max_acceleration': [1, 1]},
     "setpoint max_acceleration has 2 values for 3 outputs ['x', 'y', 'z']")])
def test_a_setpoint_list_neither_one_nor_one_per_output_is_refused(config, task, setpoint, message):
    """Any list of numbers of a setpoint section is per output. A profile's limits were not checked:
    a numpy broadcast error and Safety when the Task first ran, and a Task not active at the start
    (Retreat) ran to exit 0 and would have failed only when switched on."""
    edit_yaml(config / 'tasks' / f'{task}.yaml', lambda t: t.update(setpoint=setpoint))
    err = refused(_app(config))
    assert (err.file, err.message) == (str(config / 'tasks' / f'{task}.yaml'), message), str(err)


def test_a_name_too_long_for_a_ros_namespace_is_refused(config):
    """A 300-character application name passed and the bootstrap died making its lock file (a
    traceback, exit 1); a name is a ROS name token of at most 64 characters."""
    edit_yaml(_app(config), lambda a: a['application'].update(name='a' * 65))
    err = refused(_app(config))
    assert (err.file, err.path) == (str(_app(config)), 'application.name'), str(err)
    assert "pattern '^[A-Za-z][A-Za-z0-9_]{0,63}$'" in err.message, str(err)


def test_a_priority_beyond_what_the_rows_message_carries_is_refused(config):
    """10^30 passed and rclpy refused it as the Rows entity's parameter after the start (a traceback
    and exit 2); ``ConstraintRows.priority`` is a uint32."""
    task = config / 'tasks' / 'approach_object.yaml'
    edit_yaml(task, lambda t: t.update(priority=10 ** 30))
    err = refused(_app(config))
    assert (err.file, err.path) == (str(task), 'priority'), str(err)
    assert err.message.startswith('Input should be less than or equal to 4294967295'), str(err)


def test_a_section_written_as_its_kind_alone_is_named_as_such(config):
    """``solver: qp`` was reported as ``solver.kind: required field is missing``, although the kind
    was there: the section is what is wrong."""
    edit_yaml(_program(config), lambda p: p.update(solver='qp'))
    err = refused(_app(config))
    assert (err.file, err.path, err.message) == (
        str(_program(config)), 'solver', "expected a section ({kind: ..., ...}), got 'qp'"), str(err)


@pytest.mark.parametrize('include', [{'include': '../programs/approach_object.yaml', 'name': 'x'}, {'include': 5}])
def test_an_include_with_other_fields_or_no_file_name_is_refused_as_an_include(config, include):
    """Before, it was taken as the section itself (``application.program.robots: required field is
    missing``)."""
    edit_yaml(_app(config), lambda a: a['application'].update(program=include))
    err = refused(_app(config))
    assert (err.file, err.path) == (str(_app(config)), 'application.program.include'), str(err)
    assert err.message == f'an include is {{include: FILE}} alone (a file name, no other field), got {include!r}'


@pytest.mark.parametrize('file, edit, path', [
    ('apps/approach_object.yaml', lambda a: a['application'].update(rate=True), 'application.rate'),
    ('tasks/approach_object.yaml', lambda t: t.update(priority=True), 'priority'),
    ('tasks/approach_object.yaml', lambda t: t.update(weights=[1.0, False]), 'weights')])
def test_true_or_false_where_a_number_is_expected_is_refused(config, file, edit, path):
    """Pydantic's lax mode read ``rate: true`` as 1 Hz and ``priority: true`` as level 1."""
    edit_yaml(config / file, edit)
    err = refused(_app(config))
    assert (err.file, err.path) == (str(config / file), path), str(err)
    assert err.message.startswith('expected a number, got true') or err.message == \
        'expected numbers, got [1.0, false]', str(err)


def test_states_that_leave_each_other_at_once_forever_are_refused(config):
    """Two states each raising on entry the event that leaves it for the other: the program
    switched at every pass (177 console lines in 2 s, the rate halved) and the run ended exit 0."""
    def edit(program: dict) -> None:
        states = program['running']['states']
        states['hold']['raise'], states['retreat']['raise'] = ['e_go'], ['e_back']
        program['running']['transitions'] += [{'from': 'hold', 'to': 'retreat', 'when': 'e_go'},
                                              {'from': 'retreat', 'to': 'hold', 'when': 'e_back'}]
    edit_yaml(_program(config), edit)
    err = refused(_app(config))
    assert (err.file, err.path, err.message) == (
        str(_program(config)), 'running.states.hold.raise',
        'states hold -> retreat -> hold would switch forever: each raises on entry an event that leaves it for the '
        'next'), str(err)


def test_an_object_position_with_nan_is_refused(config):
    edit_yaml(_program(config), lambda p: p['objects'][0]['xyz'].__setitem__(2, math.nan))
    err = refused(_app(config))
    assert (err.file, err.path) == (str(_program(config)), 'objects[0].xyz[2]'), str(err)


def test_an_initial_joint_position_in_degrees_is_refused(config):
    """-135 (degrees for -2.356 rad) is outside the joint's URDF limits: the simulated robot would
    start clamped at the limit, not where the model says."""
    ready = config / 'robots' / 'panda_ready.yaml'
    edit_yaml(ready, lambda q: q.update(panda_joint4=-135.0))
    err = refused(_app(config))
    assert (err.file, err.path) == (str(ready), 'panda_joint4'), str(err)
    assert '-135' in err.message and '[-3.0718, -0.0698]' in err.message, str(err)


def test_an_initial_joint_position_beyond_the_models_own_limits_is_refused(config):
    """The robot's ``limits`` narrow the URDF's; the initial position must be within those."""
    edit_yaml(config / 'robots' / 'panda.yaml', lambda r: r.update(limits={'panda_joint6': {'upper': 1.2}}))
    err = refused(_app(config))
    assert (err.file, err.path) == (str(config / 'robots' / 'panda_ready.yaml'), 'panda_joint6'), str(err)
    assert '1.571' in err.message and ', 1.2]' in err.message, str(err)


def test_two_robots_whose_joints_have_the_same_names_are_refused(config):
    """Two Pandas from one URDF: the Scene and the Solver know joints by name. Before, the model was
    taken and the deployment failed after the start (Safety, 'use Robot(prefix=...)')."""
    edit_yaml(_program(config), lambda p: p['robots'].append({'name': 'twin', 'urdf': 'panda.urdf',
                                                               'xyz': [0.0, 1.0, 0.0]}))
    edit_yaml(_app(config), lambda a: a['application']['drivers'].append({'robot': 'twin', 'kind': 'simulated'}))
    err = refused(_app(config))
    assert (err.file, err.path) == (str(_program(config)), 'robots[1].urdf'), str(err)
    assert "robot 'twin' has joints of the same names as robot 'panda' (panda_joint1, " in err.message, str(err)


@pytest.mark.parametrize('field, task, value', [
    ('outputs', 'retreat', ['x', 'z', 'x']),  # a Cartesian Task's x twice: its row twice
    ('joints', 'posture', ['panda_joint1', 'panda_joint2', 'panda_joint1']),
])
def test_a_name_given_twice_in_a_tasks_outputs_or_joints_is_refused(config, field, task, value):
    path = config / 'tasks' / f'{task}.yaml'
    if task == 'posture':
        path.write_text(yaml.safe_dump({'name': 'Posture', 'type': 'joint', 'controller': {'kind': 'p', 'kp': 1.0}}))
        edit_yaml(_program(config), lambda p: p['tasks'].append({'include': '../tasks/posture.yaml'}))
    edit_yaml(path, lambda t: t.update({field: value}))
    err = refused(_app(config))
    assert (err.file, err.path) == (str(path), field), str(err)
    assert err.message == f"'{value[0]}' given more than once", str(err)


def test_an_entity_refuses_outputs_given_twice_as_a_parameter():
    """The same rule for a running Constraint Output (``ros2 param set .../CO outputs``)."""
    from itasc_tasks.entities.constraint_output_entity import ConstraintOutputEntity
    assert ConstraintOutputEntity.parameters_of({'outputs': ['x', 'y']}).outputs == ['x', 'y']
    with pytest.raises(ValueError, match="'y' given more than once"):
        ConstraintOutputEntity.parameters_of({'outputs': ['y', 'x', 'y']})


def test_a_monitor_threshold_of_nan_is_refused(config):
    edit_yaml(_program(config), lambda p: p['monitors'][0].update(threshold=math.nan))
    err = refused(_app(config))
    assert (err.file, err.path) == (str(_program(config)), 'monitors[0].threshold'), str(err)


@pytest.mark.parametrize('kind', [{'a': [1]}, ['cartesian'], 3])
def test_a_task_type_that_is_not_a_name_is_refused(config, kind):
    task = config / 'tasks' / 'approach_object.yaml'
    edit_yaml(task, lambda t: t.update(type=kind))
    err = refused(_app(config))
    assert err.file == str(task) and 'unknown task type' in err.message, str(err)


def test_a_negative_minimum_distance_is_refused(config):
    task = config / 'tasks' / 'avoid_obstacle.yaml'
    edit_yaml(task, lambda t: t.update(d_min=-0.15))
    err = refused(_app(config))
    assert (err.file, err.path) == (str(task), 'd_min'), str(err)
    assert '-0.15' in err.message, str(err)


def test_a_minimum_distance_above_the_maximum_is_refused(config):
    task = config / 'tasks' / 'avoid_obstacle.yaml'
    edit_yaml(task, lambda t: t.update(d_min=0.3, d_max=0.2))
    err = refused(_app(config))
    assert (err.file, err.path) == (str(task), 'd_max'), str(err)
    assert '0.2' in err.message and '0.3' in err.message, str(err)


def test_a_key_given_twice_is_refused(config):
    app = _app(config)
    app.write_text(app.read_text().replace('  rate: 100\n', '  rate: 100\n  rate: 5\n'))
    err = refused(app)
    assert (err.file, err.path) == (str(app), 'application.rate'), str(err)
    assert 'twice' in err.message, str(err)


def test_a_binary_file_is_refused(config):
    app = _app(config)
    app.write_bytes(bytes(range(256)) * 8)
    err = refused(app)
    assert (err.file, err.path) == (str(app), 'line 2, column 118'), str(err)  # 0x80, after 0x0a
    assert '0x80' in err.message, str(err)


def test_a_latin1_file_is_refused(config):
    app = _app(config)
    app.write_bytes(app.read_text().replace('# The paper', '# Caf\xe9: the paper').encode('latin-1'))
    err = refused(app)
    assert (err.file, err.path) == (str(app), 'line 1, column 6'), str(err)
    assert 'UTF-8' in err.message and '0xe9' in err.message, str(err)


def test_deeply_nested_lists_are_refused(config):
    app = _app(config)
    app.write_text(app.read_text().replace('  rate: 100\n', '  rate: ' + '[' * 20000 + ']' * 20000 + '\n'))
    err = refused(app)
    assert err.file == str(app) and err.path.startswith('application.rate[0][0]'), str(err)
    assert f'deeper than {MAX_DEPTH}' in err.message, str(err)


def test_deep_nesting_through_includes_is_refused(config):
    for k in range(MAX_DEPTH + 1):
        (config / f'n{k}.yaml').write_text(f'inner: {{include: n{k + 1}.yaml}}\n')
    (config / f'n{MAX_DEPTH + 1}.yaml').write_text('1\n')
    edit_yaml(_program(config), lambda p: p['tasks'].__setitem__(0, {'include': '../n0.yaml'}))
    err = refused(_app(config))
    assert f'deeper than {MAX_DEPTH}' in err.message and err.path, str(err)


def test_an_include_of_dev_zero_is_refused(config):
    edit_yaml(_program(config), lambda p: p['tasks'].__setitem__(0, {'include': '/dev/zero'}))
    err = refused(_app(config))
    assert (err.file, err.path) == (str(_program(config)), 'tasks[0].include'), str(err)
    assert '/dev/zero' in err.message and 'outside' in err.message, str(err)


@pytest.mark.parametrize('special', ['fifo', 'directory', 'oversized'])
def test_an_include_of_a_special_or_oversized_file_is_refused(config, special):
    target = config / 'tasks' / 'special.yaml'
    if special == 'fifo':
        os.mkfifo(target)
    elif special == 'directory':
        target.mkdir()
    else:
        target.write_text('name: x\n' + '#' * MAX_BYTES + '\n')
    edit_yaml(_program(config), lambda p: p['tasks'].__setitem__(0, {'include': '../tasks/special.yaml'}))
    err = refused(_app(config))
    assert (err.file, err.path) == (str(_program(config)), 'tasks[0].include'), str(err)
    assert 'special.yaml' in err.message, str(err)


def test_an_include_outside_the_model_folders_is_refused(config, tmp_path):
    outside = tmp_path / 'elsewhere.yaml'
    outside.write_text((config / 'tasks' / 'retreat.yaml').read_text())
    edit_yaml(_program(config), lambda p: p['tasks'].__setitem__(2, {'include': '../../elsewhere.yaml'}))
    err = refused(_app(config))
    assert (err.file, err.path) == (str(_program(config)), 'tasks[2].include'), str(err)
    assert str(outside) in err.message and 'outside' in err.message, str(err)


def test_a_model_file_beyond_the_size_limit_is_refused_without_parsing_it(config):
    app = _app(config)
    with app.open('a') as stream:
        stream.write('# ' + 'x' * 1000 + '\n')
        stream.write(('    - [' + ', '.join(['0.5'] * 100) + ']\n') * (50 * MAX_BYTES // 500))
    assert app.stat().st_size > 50 * MAX_BYTES
    err = refused(app)
    assert err.file == str(app) and f'larger than {MAX_BYTES} bytes' in err.message, str(err)


def test_too_many_values_are_refused(config):
    edit_yaml(_program(config), lambda p: p.update(name=[[0] * 1000] * (MAX_VALUES // 1000 + 1)))
    err = refused(_app(config))
    assert err.file == str(_program(config)) and err.path.startswith('name['), str(err)


def test_a_task_included_twice_is_reported_against_the_including_program(config):
    edit_yaml(_program(config), lambda p: p['tasks'].append({'include': '../tasks/retreat.yaml'}))
    err = refused(_app(config))
    assert (err.file, err.path) == (str(_program(config)), 'tasks[3].include'), str(err)
    assert 'included twice' in err.message and 'tasks[2]' in err.message, str(err)


# -- pattern models: kinds and ports at load time ---------------------------------------------------------

def test_an_unknown_entity_kind_of_a_pattern_model_is_refused_at_load_time(config):
    program = config / 'pattern' / 'program.yaml'
    edit_yaml(program, lambda p: p['entities'][2].update(kind='Mixer'))
    err = refused(config / 'apps' / 'pattern_demo.yaml')
    assert (err.file, err.path) == (str(program), 'entities[2].kind'), str(err)
    assert "'Mixer'" in err.message, str(err)


def test_an_unknown_port_of_a_pattern_model_is_refused_at_load_time(config):
    program = config / 'pattern' / 'program.yaml'
    edit_yaml(program, lambda p: p['connections'][0].update({'from': 'track.commands'}))
    err = refused(config / 'apps' / 'pattern_demo.yaml')
    assert (err.file, err.path) == (str(program), 'connections[0].from'), str(err)
    assert 'commands' in err.message, str(err)


def test_an_unknown_parameter_of_a_pattern_entity_is_refused_at_load_time(config):
    app = config / 'apps' / 'pattern_demo.yaml'
    edit_yaml(app, lambda a: a['composite']['entities'][1].update(parameters={'sise': 2}))
    err = refused(app)
    assert (err.file, err.path) == (str(app), 'composite.entities[1].parameters.sise'), str(err)


def test_a_kind_naming_a_module_is_never_imported(config, tmp_path, monkeypatch):
    marker = tmp_path / 'imported'
    (tmp_path / 'model_code.py').write_text(f'open({str(marker)!r}, "w").close()\nclass Thing: pass\n')
    monkeypatch.syspath_prepend(str(tmp_path))
    app = config / 'apps' / 'pattern_demo.yaml'
    edit_yaml(app, lambda a: a['composite']['entities'][1].update(kind='model_code:Thing'))
    err = refused(app)
    assert (err.file, err.path) == (str(app), 'composite.entities[1].kind'), str(err)
    assert not marker.exists(), 'a kind in the model imported code'
    assert 'model_code' not in sys.modules


def test_kinds_are_the_registered_ones_and_those_of_the_entry_point_group(tmp_path, monkeypatch):
    for target in transform.KINDS.values():  # what the iTaSC transformation produces
        assert known_kind(target) and resolve_kind(target).__name__ == target.split(':')[1]
    assert not known_kind('PluginSine')
    dist = tmp_path / 'itasc_plugin-1.0.dist-info'
    dist.mkdir()
    (dist / 'METADATA').write_text('Metadata-Version: 2.1\nName: itasc-plugin\nVersion: 1.0\n')
    (dist / 'entry_points.txt').write_text(
        f'[{ENTRY_POINTS}]\nPluginSine = itasc_core.computation.library:SineSource\n')
    monkeypatch.syspath_prepend(str(tmp_path))
    assert known_kind('PluginSine') and resolve_kind('PluginSine') is SineSource


# -- the property: mutations along the schema of the shipped models, all refused ---------------------------

#: The files of approach_object and where each lies in the application model.
FILES = {
    'apps/approach_object.yaml': (),
    'programs/approach_object.yaml': ('application', 'program'),
    'tasks/approach_object.yaml': ('application', 'program', 'tasks', 0),
    'tasks/avoid_obstacle.yaml': ('application', 'program', 'tasks', 1),
    'tasks/retreat.yaml': ('application', 'program', 'tasks', 2),
    'robots/panda.yaml': ('application', 'program', 'robots', 0),
    'robots/panda_ready.yaml': ('application', 'drivers', 0, 'initial'),
}
#: Fields that name something else in the model, and a name nothing has.
REFERENCES = {'o1': 'nope/frame', 'o2': 'nope/frame', 'watch': 'Nope.error', 'link': 'nope_link',
              'urdf': 'nope.urdf', 'robot': 'nope', 'from': 'nope', 'to': 'nope', 'initial': 'nope',
              'when': 'e_nope', 'tasks': 'Nope', 'monitors': 'nope', 'configure': 'nope'}
MUTATIONS = ('wrong_type', 'non_finite', 'out_of_range', 'missing_key', 'extra_key', 'unknown_name',
             'dangling_include', 'cyclic_include', 'huge', 'deep', 'encoding', 'duplicate_key')


def _nodes(value: Any, loc: tuple = ()):
    yield loc, value
    if isinstance(value, dict):
        for k, v in value.items():
            yield from _nodes(v, loc + (k,))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            yield from _nodes(v, loc + (i,))


def _schema_at(loc: tuple, value: Any = None) -> tuple[Any, Any]:
    """The annotation of the application model at ``loc`` (of the registered kind ``value`` names,
    where the section has one per kind), and the pydantic field it is (or None)."""
    annotation, field = typing.Dict[str, Application], None
    for part in loc:
        annotation = _unwrap(annotation, has=part)
        if isinstance(annotation, type) and issubclass(annotation, BaseModel):
            field = next(f for n, f in annotation.model_fields.items() if part in (n, f.alias))
            annotation = field.annotation
            continue
        args = typing.get_args(annotation)
        annotation = args[-1] if typing.get_origin(annotation) is dict else args[0]
        field = None
    return _unwrap(annotation, value), field


def _unwrap(annotation: Any, value: Any = None, *, has: Any = None) -> Any:
    """The member of a union that ``value`` is a section of, or that has the field ``has``."""
    while typing.get_origin(annotation) in (typing.Union, typing.Annotated, types.UnionType):
        members = [a for a in typing.get_args(annotation) if a is not type(None)]
        annotation = next((a for a in members if _names_kind(_unwrap(a), value) or _has(_unwrap(a), has)),
                          members[0])
    return annotation


def _has(model: Any, field: Any) -> bool:
    return field is not None and isinstance(model, type) and issubclass(model, BaseModel) and any(
        field in (n, f.alias) for n, f in model.model_fields.items())


def _names_kind(model: Any, value: Any) -> bool:
    """Whether ``value`` (a mapping) is a section of ``model``, by the kinds its Literal fields fix."""
    if not (isinstance(value, dict) and isinstance(model, type) and issubclass(model, BaseModel)):
        return False
    return all(value.get(f.alias or n, f.default) in typing.get_args(f.annotation)
               for n, f in model.model_fields.items() if typing.get_origin(f.annotation) is typing.Literal)


def _locs(data: Any, site: tuple, where) -> list[tuple]:
    return [loc for loc, value in _nodes(data) if 'include' not in loc and where(loc, value, site)]


def _leaf(loc, value, site):
    return not isinstance(value, (dict, list)) and not isinstance(value, bool)


def _number(loc, value, site):
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _bounded(loc, value, site):
    if not _number(loc, value, site) or not loc or isinstance(loc[-1], int):
        return False
    _, field = _schema_at(site + loc)
    bound = field is not None and any(isinstance(m, (annotated_types.Gt, annotated_types.Ge)) for m in field.metadata)
    return bound or loc[-1] == 'd_min'


def _model_mapping(loc, value, site):
    return isinstance(value, dict) and set(value) != {'include'} and \
        isinstance(_schema_at(site + loc)[0], type) and issubclass(_schema_at(site + loc)[0], BaseModel)


def _required(loc, value, site):
    return _model_mapping(loc, value, site) and bool(_required_keys(site + loc, value))


def _required_keys(loc: tuple, value: dict) -> list[str]:
    """The keys of ``value`` its section requires (not the kind field of a kind the section takes
    by default when it is left out)."""
    keys = []
    for n, f in _schema_at(loc, value)[0].model_fields.items():
        key = f.alias or n
        if not (f.is_required() and key in value):
            continue
        rest = {k: v for k, v in value.items() if k != key}
        other = _schema_at(loc, rest)[0]
        if not (_names_kind(other, rest) and n in other.model_fields and not other.model_fields[n].is_required()):
            keys.append(key)
    return keys


def _mapping(loc, value, site):
    return isinstance(value, dict) and set(value) != {'include'}


def _reference(loc, value, site):
    key = next((p for p in reversed(loc) if isinstance(p, str)), None)
    return isinstance(value, str) and key in REFERENCES and (loc[-1] == key or key in ('when', 'tasks', 'monitors',
                                                                                         'configure'))


def _include_site(loc, value, site):
    return isinstance(value, dict) and set(value) == {'include'}


@st.composite
def mutations(draw):
    name = draw(st.sampled_from(sorted(FILES)))
    data = yaml.safe_load((REPO / 'config' / name).read_text())
    kind = draw(st.sampled_from(MUTATIONS))
    site = FILES[name]
    where = {'wrong_type': _leaf, 'non_finite': _number, 'out_of_range': _bounded, 'missing_key': _required,
             'extra_key': _mapping, 'unknown_name': _reference, 'huge': _leaf, 'deep': _leaf,
             'duplicate_key': lambda loc, v, s: _mapping(loc, v, s) and v}.get(kind)
    if kind in ('dangling_include', 'cyclic_include'):
        candidates = [loc for loc, value in _nodes(data) if _include_site(loc, value, site)] if kind == \
            'dangling_include' else [loc for loc, value in _nodes(data) if _mapping(loc, value, site)]
    elif where is not None:
        candidates = _locs(data, site, where)
    else:
        candidates = [()]
    if not candidates:
        kind, candidates = 'encoding', [()]
    loc = draw(st.sampled_from(candidates))
    extra = draw(st.integers(min_value=0, max_value=2))
    return name, kind, loc, extra


def _at(data: Any, loc: tuple) -> Any:
    for part in loc:
        data = data[part]
    return data


def _put(data: Any, loc: tuple, value: Any) -> Any:
    if not loc:
        return value
    _at(data, loc[:-1])[loc[-1]] = value
    return data


def _mutate(config: Path, name: str, kind: str, loc: tuple, extra: int) -> tuple[str, Any]:
    """Break file ``name`` in ``config``; returns the path the error must start with and the value."""
    file = config / name
    data = yaml.safe_load(file.read_text())
    value = _at(data, loc)
    at = format_loc(loc)
    if kind == 'encoding':
        raw = file.read_bytes()
        file.write_bytes([b'# caf\xe9\n' + raw, raw.decode().encode('utf-16'), b'a: \x00\n' + raw][extra])
        return 'line ', None
    if kind == 'duplicate_key':
        key, first = next(iter(value.items()))
        twice = f'{json.dumps(key)}: {json.dumps(first)}'
        if not loc:
            file.write_text(file.read_text() + f'\n{twice}\n')
        else:
            text = yaml.safe_dump(_put(data, loc, 'DUPLICATE_HERE'), sort_keys=False)
            file.write_text(text.replace('DUPLICATE_HERE', f'{{{twice}, {twice}}}', 1))
        return format_loc(loc + (key,)), None
    bad: Any
    if kind == 'wrong_type':
        bad, expect = ('not a number' if _number(loc, value, ()) else {'a': [1]}), at
    elif kind == 'non_finite':
        bad, expect = [math.nan, math.inf, -math.inf][extra], at
    elif kind == 'out_of_range':
        bad, expect = (-1 if isinstance(value, int) else -abs(value) - 0.5), at
    elif kind == 'missing_key':
        key = _required_keys(FILES[name] + loc, value)[0]
        bad, expect = {k: v for k, v in value.items() if k != key}, format_loc(loc + (key,))
    elif kind == 'extra_key':
        bad, expect = {**value, 'bogus_key': {'bogus': 1}}, format_loc(loc + ('bogus_key',))
    elif kind == 'unknown_name':
        key = next(p for p in reversed(loc) if isinstance(p, str))
        bad, expect = REFERENCES[key], at
    elif kind == 'dangling_include':
        bad, expect = {'include': 'missing_nope.yaml'}, format_loc(loc + ('include',))
    elif kind == 'cyclic_include':
        bad = {'include': os.path.relpath(config / 'apps' / 'approach_object.yaml', file.parent)}
        expect = format_loc(loc + ('include',))
    elif kind == 'huge':
        text = yaml.safe_dump(_put(data, loc, 'HUGE_HERE'), sort_keys=False)
        file.write_text(text.replace('HUGE_HERE', '[' + '0, ' * MAX_VALUES + '0]', 1))
        return at, None
    else:  # deep
        bad = nested = []
        for _ in range(MAX_DEPTH + extra * 50):
            nested.append([])
            nested = nested[0]
        expect = at
    file.write_text(yaml.safe_dump(_put(data, loc, bad), sort_keys=False, default_flow_style=kind == 'deep'))
    return expect, bad


@pytest.fixture(scope='module')
def shipped(tmp_path_factory) -> Path:
    config = tmp_path_factory.mktemp('shipped') / 'config'
    shutil.copytree(REPO / 'config', config)
    return config


@settings(max_examples=300, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(mutation=mutations())
def test_every_mutation_of_a_shipped_model_is_refused_naming_file_and_path(shipped, mutation):
    name, kind, loc, extra = mutation
    file = shipped / name
    original = file.read_bytes()
    try:
        expect, bad = _mutate(shipped, name, kind, loc, extra)
        err = refused(shipped / 'apps' / 'approach_object.yaml')
    finally:
        file.write_bytes(original)
    assert err.file == str(file), f'{kind} at {name}:{format_loc(loc)}: {err}'
    assert err.path and err.path.startswith(expect), f'{kind} at {name}:{format_loc(loc)}: {err}'
    if kind == 'non_finite':
        assert str(bad) in err.message, str(err)


# -- through the real bootstrap: exit 2, file and path on stderr, no traceback, no DDS participant ---------

def _bootstrap(model: Path) -> tuple[int, str, float, set[str], int]:
    """Run the bootstrap on ``model``; its exit code, stderr, run time, the names of its threads seen
    while it ran and its peak memory (kB)."""
    threads: set[str] = set()
    peak = 0
    start = time.monotonic()
    with Spawned([sys.executable, '-m', 'itasc_bringup.bootstrap', str(model), '--duration', '0.5']) as app:
        while app.process.poll() is None and time.monotonic() - start < 30:
            try:
                for task in os.listdir(f'/proc/{app.process.pid}/task'):
                    with open(f'/proc/{app.process.pid}/task/{task}/comm') as comm:
                        threads.add(comm.read().strip())
                with open(f'/proc/{app.process.pid}/status') as status:
                    peak = max([peak] + [int(line.split()[1]) for line in status if line.startswith('VmHWM')])
            except (OSError, ValueError):
                pass
            time.sleep(0.005)
        code = app.finish(timeout=30)
        return code, app.err + app.out, time.monotonic() - start, threads, peak


def _cases(config: Path, tmp_path: Path) -> list[tuple[Path, str]]:
    huge = tmp_path / 'huge.yaml'
    with huge.open('w') as stream:
        stream.write('application:\n  rates:\n')
        stream.write(('    - [' + ', '.join(['0.5'] * 100) + ']\n') * (50 * MAX_BYTES // 500))
    twice = tmp_path / 'twice.yaml'
    twice.write_text(_app(config).read_text().replace('  rate: 100\n', '  rate: 100\n  rate: 5\n'))
    deep = tmp_path / 'deep.yaml'
    deep.write_text('application:\n  rate: ' + '[' * 20000 + ']' * 20000 + '\n')
    edit_yaml(_program(config), lambda p: p['tasks'].__setitem__(0, {'include': '/dev/zero'}))
    kind = config / 'pattern' / 'program.yaml'
    edit_yaml(kind, lambda p: p['entities'][2].update(kind='Mixer'))
    return [(huge, f'{huge}: '), (twice, f'{twice}: application.rate: '), (deep, f'{deep}: application.rate[0]'),
            (_app(config), f'{_program(config)}: tasks[0].include: '),
            (config / 'apps' / 'pattern_demo.yaml', f'{kind}: entities[2].kind: ')]


def test_the_bootstrap_refuses_bad_models_with_exit_2_fast_and_starts_nothing(config, tmp_path):
    for model, named in _cases(config, tmp_path):
        code, output, elapsed, threads, peak = _bootstrap(model)
        assert code == 2, f'{model}: exit {code}\n{output[-3000:]}'
        assert named in output and 'Traceback' not in output, output[-3000:]
        assert elapsed < 5.0, f'{model}: refused after {elapsed:.1f} s'
        assert peak < 500_000, f'{model}: {peak} kB'
        assert threads and not any(name.startswith('dds.') for name in threads), threads


@pytest.mark.parametrize('option, value, message', [
    ('--rate', 'nan', '--rate must be between 0.01 and 100000 Hz (got nan)'),
    ('--rate', 'inf', '--rate must be between 0.01 and 100000 Hz (got inf)'),
    ('--rate', '1e-9', '--rate must be between 0.01 and 100000 Hz (got 1e-09)'),
    ('--duration', 'nan', '--duration must be a finite number of seconds > 0 (got nan)'),
    ('--duration', 'inf', '--duration must be a finite number of seconds > 0 (got inf)')])
def test_the_bootstrap_refuses_a_rate_or_duration_that_is_no_number_of_seconds(capsys, option, value, message):
    """``--rate nan`` failed in the Timer after the bring-up began (a traceback), ``--rate inf`` in
    an overflow, and ``--duration nan`` never stopped; ``--rate`` skips the model's validation."""
    from itasc_bringup.bootstrap import parse_args
    with pytest.raises(SystemExit) as exit_:
        parse_args(['approach_object', option, value])
    assert exit_.value.code == 2
    assert capsys.readouterr().err.splitlines()[-1] == f'bootstrap: error: {message}'


@pytest.mark.parametrize('content, said', [
    ('not xml at all', 'Error: Error=XML_ERROR_PARSING_TEXT ErrorID=8 (0x8) Line number=1'),
    ('<robot name="x"><link name="a"/><joint name="j" type="revolute"><parent link="a"/><child link="b"/></joint>'
     '</robot>', 'Error: Joint [j] is of type REVOLUTE but it does not specify limits')])
def test_a_urdf_the_parser_refuses_is_one_line_with_what_the_parser_said(config, content, said):
    """The URDF parser prints its reasons on stderr itself, with its own source locations
    (``at line 103 in /project/urdfdom/...``): they came before the error line, which was no longer
    one line. What it says is part of the error now."""
    (config / 'robots' / 'panda.urdf').write_text(content)
    code, output, _, _, _ = _bootstrap(_app(config))
    assert code == 2, output
    assert output.strip().count('\n') == 0 and output.startswith(
        f"error: {config / 'robots' / 'panda.yaml'}: urdf: URDF 'panda.urdf' cannot be loaded: "), output
    assert said in output and 'urdfdom' not in output, output


def test_what_is_printed_while_a_urdf_that_loads_is_parsed_is_not_lost(capfd):
    """What anything prints while a URDF is parsed (the parser's warnings, another thread's output)
    is held back only when the parse fails, and written out otherwise."""
    from itasc_bringup.model.checks import _stderr_kept
    with _stderr_kept() as said:
        os.write(2, b'a warning of another thread\n')
    assert capfd.readouterr().err == 'a warning of another thread\n'
    with pytest.raises(ValueError), _stderr_kept() as said:
        os.write(2, b'Error: no robot at line 103 in /project/urdfdom/model.cpp\n')
        raise ValueError('not a URDF')
    assert capfd.readouterr().err == '' and said() == 'Error: no robot'

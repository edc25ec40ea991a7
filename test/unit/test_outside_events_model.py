"""Outside events in the model (issue #14 item 3): mapping an unknown message or service type, or
a field the type does not have, is a model error like any other - the file and the path named,
exit 2 from the bootstrap, nothing started. A Running sub-FSM may wait for a mapped event."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from model_files import edit_yaml
from processes import Spawned

from itasc_bringup.apps import load_composition
from itasc_core.composition.loader import ModelError


def _pick(config: Path) -> Path:
    return config / 'apps' / 'pick_with_gripper.yaml'


def _event(config: Path, k: int, **changes) -> None:
    edit_yaml(_pick(config), lambda d: d['application']['events'][k].update(changes))


def refused(app: Path) -> ModelError:
    with pytest.raises(ModelError) as info:
        load_composition(str(app))
    return info.value


def test_the_shipped_pick_maps_a_topic_and_a_service_into_the_program():
    program = next(c for c in load_composition('pick_with_gripper').children if c.name == 'itasc')
    assert [(e.topic, e.service, e.event) for e in program.events] == [
        ('/gripper/object_grasped', None, 'e_object_grasped'), (None, 'object_grasped', 'e_object_grasped')]


@pytest.mark.parametrize('changes, path, words', [
    ({'type': 'std_msgs/msg/Boool'}, 'events[0].type', ["unknown message type 'std_msgs/msg/Boool'", "'Bool'"]),
    ({'type': 'gripper_msgs/msg/Grasp'}, 'events[0].type', ["no installed package 'gripper_msgs'"]),
    ({'type': 'std_srvs/srv/Trigger'}, 'events[0].type', ['is a service type; a message type is expected']),
    ({'field': 'grasped'}, 'events[0].field', ["has no field 'grasped'", "['data']"]),
    ({'value': 'yes'}, 'events[0].value', ["'yes' is no boolean value"]),
    ({'service': 'grasped'}, 'events[0]', ['give a topic or a service']),
])
def test_a_wrong_topic_mapping_is_refused_naming_file_and_path(config, changes, path, words):
    _event(config, 0, **changes)
    err = refused(_pick(config))
    assert err.file == str(_pick(config)) and err.path == f'application.{path}', str(err)
    for word in words:
        assert word in err.message, str(err)


def test_a_wrong_service_mapping_is_refused_naming_file_and_path(config):
    _event(config, 1, type='std_msgs/msg/Bool')
    err = refused(_pick(config))
    assert (err.file, err.path) == (str(_pick(config)), 'application.events[1].type'), str(err)
    _event(config, 1, type='std_srvs/srv/Trigger', field='data', value=True)
    err = refused(_pick(config))
    assert err.path == 'application.events[1].field' and "has no field 'data'" in err.message, str(err)


def test_an_event_the_running_sub_fsm_waits_for_needs_someone_to_raise_it(config):
    edit_yaml(_pick(config), lambda d: d['application'].pop('events'))
    err = refused(_pick(config))
    program = config / 'programs' / 'pick_with_gripper.yaml'
    assert (err.file, err.path) == (str(program), 'running.transitions[1].when[0]'), str(err)
    assert "'e_object_grasped' is raised by nobody" in err.message


def test_a_pattern_model_s_outside_event_is_checked_too(config):
    program = config / 'pattern' / 'program.yaml'
    edit_yaml(program, lambda d: d.update(events=[{'topic': '/plc/go', 'type': 'std_msgs/msg/Empty', 'field': 'data',
                                               'value': True, 'event': 'e_go'}]))
    err = refused(config / 'apps' / 'pattern_demo.yaml')
    assert (err.file, err.path) == (str(program), 'events[0].field'), str(err)
    assert "std_msgs/msg/Empty has no field 'data'" in err.message, str(err)


def test_the_bootstrap_exits_2_naming_file_and_path_and_starts_nothing(config):
    _event(config, 0, type='std_msgs/msg/Boool')
    with Spawned([sys.executable, '-m', 'itasc_bringup.bootstrap', str(_pick(config))]) as app:
        assert app.finish(timeout=60) == 2, app.output()
    assert f'{_pick(config)}: application.events[0].type: unknown message type' in app.err, app.output()
    assert 'Traceback' not in app.err and '[state]' not in app.out

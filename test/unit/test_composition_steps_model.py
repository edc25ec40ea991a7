"""Composition steps in the iTaSC model (issue #14 item 2; paper §3.1): what the shipped
pick_and_retreat's step becomes in the composition model, and every step that cannot be run is a
model error naming the file and the path, before anything starts."""

from __future__ import annotations

from pathlib import Path

import pytest
from model_files import edit_yaml

from itasc_bringup.apps import load_composition
from itasc_core.composition.loader import ModelError
from itasc_core.composition.recompose import plan_step


def _program(config: Path) -> Path:
    return config / 'programs' / 'pick_and_retreat.yaml'


def refused(config: Path) -> ModelError:
    with pytest.raises(ModelError) as info:
        load_composition(str(config / 'apps' / 'pick_and_retreat.yaml'))
    return info.value


def test_a_step_of_the_program_is_a_step_of_the_program_composite_and_of_each_swapped_task():
    program = load_composition('pick_and_retreat').entity('itasc')
    step = program.composition_steps['retreat']
    assert (step.remove, step.children) == (['AvoidObstacle'], {'ApproachObject': 'retreat'})
    swap = program.entity('ApproachObject').composition_steps['retreat'].swap
    controller, setpoint = (next(e for e in swap if e.name == name).parameters for name in ('CC', 'SPG'))
    assert (controller['kind'], controller['kp'], controller['max_output']) == ('p', 1.0, 0.1)
    assert setpoint['pose'] == {'xyz': (0.0, 0.0, -0.15), 'rpy': (0.0, 0.0, 0.0)} and setpoint['duration'] == 3.0
    # entering 'retreat' runs it; its answer moves the Running sub-FSM on
    assert program.running.states['retreat'].raise_ == ['e_itasc_compose_retreat']
    assert any(t.when == ['e_itasc_composed'] for t in program.running.transitions)
    # and it fits the program as it starts: one Task fewer, the swap in the Task
    assert [e.name for e in plan_step(program, '/pick_and_retreat/itasc', 'retreat').model.children] == \
        ['ApproachObject']
    plan = plan_step(program.entity('ApproachObject'), '/pick_and_retreat/itasc/ApproachObject', 'retreat')
    assert [new.name for _, new in plan.swapped] == ['CC', 'SPG']


def test_a_task_added_by_a_step_is_related_by_the_scene_and_connected_to_the_solver(config):
    edit_yaml(_program(config), lambda p: p['composition'].update(
        back={'add': [{'include': '../tasks/avoid_obstacle.yaml'}]}, retreat={'remove': ['AvoidObstacle']}))
    edit_yaml(_program(config), lambda p: p['tasks'].pop(1))  # AvoidObstacle only comes with 'back'
    program = load_composition(str(config / 'apps' / 'pick_and_retreat.yaml')).entity('itasc')
    step = program.composition_steps['back']
    assert [e.name for e in step.add] == ['AvoidObstacle']
    assert [(c.source, c.target) for c in step.connections] == [
        ('Scene.relation_AvoidObstacle', 'AvoidObstacle.relation'), ('AvoidObstacle.rows', 'Solver.rows')]
    assert any('AvoidObstacle' in r for r in program.entity('Scene').parameters['relations'])
    plan = plan_step(program, '/pick_and_retreat/itasc', 'back')
    assert [c.name for c in plan.model.children] == ['ApproachObject', 'AvoidObstacle']


def test_a_step_can_swap_the_solver(config):
    edit_yaml(_program(config), lambda p: p['composition'].update(least_squares={'solver': {'kind': 'wdls'}}))
    program = load_composition(str(config / 'apps' / 'pick_and_retreat.yaml')).entity('itasc')
    (solver,) = program.composition_steps['least_squares'].swap
    assert solver.name == 'Solver' and solver.parameters['kind'] == 'wdls'
    assert program.entity('Solver').parameters['kind'] == 'qp'
    after = plan_step(program, '/pick_and_retreat/itasc', 'least_squares').model
    assert after.entity('Solver').parameters['kind'] == 'wdls'


@pytest.mark.parametrize('step, path, words', [
    ({'remove': ['Nobody']}, 'composition.bad.remove[0]', ["unknown task 'Nobody'"]),
    ({'remove': ['ApproachObject']}, 'composition.bad.remove[0]', ["Monitor 'retreated' watches it"]),
    ({'swap': {'Nobody': {'controller': {'kp': 1.0}}}}, 'composition.bad.swap.Nobody', ["unknown task 'Nobody'"]),
    ({'swap': {'AvoidObstacle': {'setpoint': {'kind': 'fixed', 'value': [0.3]}}}}, 'composition.bad.swap.AvoidObstacle',
     ['an inequality task has bounds']),
    ({'swap': {'ApproachObject': {'setpoint': {'kind': 'fixed', 'value': [0.1, 0.2]}}}},
     'composition.bad.swap.ApproachObject', ['setpoint value has 2 values for 6 outputs']),
    ({'swap': {'ApproachObject': {}}}, 'composition.bad.swap.ApproachObject',
     ['swap a controller, a setpoint, or both']),
    ({'solver': {'kind': 'qp', 'backend': 'no_such_qp'}}, 'composition.bad.solver.backend',
     ["'no_such_qp' is not available"]),
    ({'add': [{'include': '../tasks/approach_object.yaml'}]}, 'composition.bad.add[0].include',
     ["duplicate task name 'ApproachObject'"]),
    ({}, 'composition.bad', ['a composition step adds, removes or swaps something']),
])
def test_a_step_that_can_never_run_is_a_model_error_naming_file_and_path(config, step, path, words):
    edit_yaml(_program(config), lambda p: p['composition'].update(bad=step))
    err = refused(config)
    assert err.file == str(_program(config)) and err.path == path, str(err)
    for word in words:
        assert word in err.message, str(err)


def test_a_state_that_runs_an_unknown_step_and_a_step_named_failed_are_model_errors(config):
    edit_yaml(_program(config), lambda p: p['running']['states']['retreat'].update(compose=['nope']))
    err = refused(config)
    assert err.path == 'running.states.retreat.compose[0]' and "unknown composition step 'nope'" in err.message, err
    edit_yaml(_program(config), lambda p: p['composition'].update(failed=p['composition']['retreat']))
    err = refused(config)
    assert err.path == 'composition' and "not be 'failed'" in err.message, err

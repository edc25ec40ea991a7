"""Planning a composition step (itasc_core.composition.recompose; paper §3.1 run-time
re-composition): the structure after the step, and every reason a step does not fit the running
composite, found before anything is built."""

from __future__ import annotations

import pytest

from itasc_core.composition.model import CompositeModel
from itasc_core.composition.recompose import StepRefused, plan_step


def task(name: str, **controller) -> dict:
    return {'name': name, 'entities': [
        {'name': 'setpoint', 'kind': 'SineSource'},
        {'name': 'controller', 'kind': 'PController', 'parameters': controller},
    ], 'connections': [{'from': 'setpoint.signal', 'to': 'controller.setpoint'}],
        'exports': {'command': 'controller.command', 'measured': 'controller.measured'}}


def program(steps: dict, **extra) -> CompositeModel:
    return CompositeModel.model_validate({
        'name': 'program',
        'entities': [task('track'), task('hold'), {'name': 'mixer', 'kind': 'Sum'}],
        'connections': [{'from': 'track.command', 'to': 'mixer.inputs'},
                        {'from': 'hold.command', 'to': 'mixer.inputs'}],
        'exports': {'command': 'mixer.sum'},
        'composition_steps': steps, **extra})


def test_removing_a_task_drops_its_connections_and_keeps_the_rest():
    plan = plan_step(program({'alone': {'remove': ['hold']}}), '/app/program', 'alone')
    assert [e.name for e in plan.model.entities] == ['track', 'mixer']
    assert [(c.source, c.target) for c in plan.model.connections] == [('track.command', 'mixer.inputs')]
    assert [(c.source, c.target) for c in plan.dropped] == [('hold.command', 'mixer.inputs')]
    assert [e.name for e in plan.removed] == ['hold'] and plan.summary() == 'removed hold'


def test_a_swap_keeps_the_entitys_place_and_its_connections():
    swap = {'name': 'controller', 'kind': 'PController', 'parameters': {'kp': 9.0}}
    model = CompositeModel.model_validate({**task('track'), 'composition_steps': {'stiff': {'swap': [swap]}}})
    plan = plan_step(model, '/app/program/track', 'stiff')
    assert [e.name for e in plan.model.entities] == ['setpoint', 'controller']
    assert plan.model.entity('controller').parameters == {'kp': 9.0}
    assert [(old.parameters, new.parameters) for old, new in plan.swapped] == [({}, {'kp': 9.0})]
    assert [(c.source, c.target) for c in plan.connections] == [('setpoint.signal', 'controller.setpoint')]


@pytest.mark.parametrize('swap, reason', [
    # the setpoint source speaks of x, this controller of y: the connection is refused, naming both ports
    ({'name': 'controller', 'kind': 'PController', 'parameters': {'semantics': 'Position(y)'}},
     "refused connection /app/program/track/setpoint.signal -> /app/program/track/controller.setpoint: "
     "semantics 'Position(x)' != 'Position(y)'"),
    # a Sum has no setpoint input
    ({'name': 'controller', 'kind': 'Sum'}, "entity 'controller' (Sum) has no port 'setpoint'"),
    # same ports for the task, but the command it exports to the parent would change its metadata
    ({'name': 'controller', 'kind': 'PController', 'parameters': {'command_semantics': 'Force(x)'}},
     "exported as 'command', its metadata would change"),
    ({'name': 'nobody', 'kind': 'PController'}, "'track' has no entity 'nobody'"),
    ({'name': 'controller', 'kind': 'NoSuchKind'}, "unknown entity kind 'NoSuchKind'"),
])
def test_a_swap_to_an_entity_whose_ports_do_not_fit_is_refused_naming_why(swap, reason):
    model = CompositeModel.model_validate({**task('track'), 'composition_steps': {'bad': {'swap': [swap]}}})
    with pytest.raises(StepRefused) as refused:
        plan_step(model, '/app/program/track', 'bad')
    assert reason in str(refused.value), str(refused.value)


@pytest.mark.parametrize('step, reason', [
    ({'remove': ['mixer']}, "'mixer' cannot be removed: it is exported to the parent as 'command'"),
    ({'remove': ['nothere']}, "'program' has no entity 'nothere'"),
    ({'add': [{'name': 'mixer', 'kind': 'Sum'}]}, "'program' already has an entity 'mixer'"),
    ({'swap': [{'name': 'track', 'kind': 'Sum'}]}, "'track' is a composite"),
    ({'children': {'gone': 'x'}}, "'program' has no child composite 'gone'"),
])
def test_steps_that_do_not_fit_the_composite_are_refused(step, reason):
    with pytest.raises(StepRefused) as refused:
        plan_step(program({'bad': step}), '/app/program', 'bad')
    assert reason in str(refused.value), str(refused.value)


def test_removing_the_only_source_of_an_input_is_refused_but_one_of_several_sources_is_not():
    model = CompositeModel.model_validate({**task('track'), 'composition_steps': {'cut': {'remove': ['setpoint']}}})
    with pytest.raises(StepRefused, match=r'controller.setpoint would lose its source setpoint.signal'):
        plan_step(model, '/app/program/track', 'cut')
    # the mixer gathers the commands of both tasks: losing one is what removing a task means
    assert plan_step(program({'alone': {'remove': ['hold']}}), '/app/program', 'alone').dropped


def test_a_removed_entity_a_monitor_watches_is_refused():
    monitors = [{'name': 'watcher', 'watch': 'hold.command', 'field': 'data', 'condition': 'above', 'event': 'e_x'}]
    with pytest.raises(StepRefused, match="Monitor 'watcher' watches it"):
        plan_step(program({'alone': {'remove': ['hold']}}, monitors=monitors), '/app/program', 'alone')


def test_a_step_is_checked_against_the_structure_as_it_is_now():
    """After 'alone' removed hold, 'back' can add it again; before, it cannot."""
    model = program({'alone': {'remove': ['hold']},
                     'back': {'add': [task('hold')], 'connections': [{'from': 'hold.command', 'to': 'mixer.inputs'}]}})
    with pytest.raises(StepRefused, match="already has an entity 'hold'"):
        plan_step(model, '/app/program', 'back')
    after = plan_step(model, '/app/program', 'alone').model
    again = plan_step(after, '/app/program', 'back')
    assert [e.name for e in again.model.entities] == ['track', 'mixer', 'hold']
    assert ('hold.command', 'mixer.inputs') in [(c.source, c.target) for c in again.connections]


def test_a_model_names_unknown_child_steps_and_overlapping_changes_as_errors():
    with pytest.raises(ValueError, match="child 'track' has no step 'nope'"):
        program({'x': {'children': {'track': 'nope'}}})
    with pytest.raises(ValueError, match=r"\['hold'\] both added and removed"):
        program({'x': {'add': [task('hold')], 'remove': ['hold']}})

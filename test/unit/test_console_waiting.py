"""What the console says a program waits for (bringup/itasc_bringup/console/waiting.py): once a
composite has stayed a while in a Running sub-FSM state that only an outside event leaves, one line
with the commands that raise the event; nothing for states the program's own Monitors leave."""

from __future__ import annotations

import yaml

from itasc_bringup.apps import load_composition
from itasc_bringup.console.facts import Transition
from itasc_bringup.console.waiting import Waits
from itasc_core.composition.model import OutsideEventModel

RUNNING = 'Active.Run.Running'


class _Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def _enter(waits: Waits, composite: str, state: str, *, event: str = 'e_x') -> None:
    waits.on_transition(Transition(composite=composite, state=f'{RUNNING}.{state}', event=event, stamp=0.0))


def test_a_program_waiting_for_the_gripper_says_so_once_with_the_commands_that_move_it_on():
    clock = _Clock()
    waits = Waits(load_composition('pick_with_gripper'), after=5.0, clock=clock)
    _enter(waits, 'itasc', 'wait_for_gripper', event='e_ApproachObject_arrived')
    clock.now += 4.9
    assert waits.due() == []
    clock.now += 0.2
    lines = waits.due()
    assert lines == [
        '[waiting] itasc: in wait_for_gripper for 5 s; it moves on at e_object_grasped: '
        'ros2 topic pub --once /gripper/object_grasped std_msgs/msg/Bool "{data: true}", '
        'or ros2 service call /pick_with_gripper/itasc/object_grasped std_srvs/srv/Trigger']
    # the request given on the command line is one the composite's mapping accepts
    request = yaml.safe_load(lines[0].split('std_msgs/msg/Bool ')[1].split(',')[0].strip('"'))
    assert request == {'data': True}
    clock.now += 60.0
    assert waits.due() == []  # once per entry into the state
    _enter(waits, 'itasc', 'retreat', event='e_object_grasped')
    _enter(waits, 'itasc', 'wait_for_gripper')
    clock.now += 6.0
    assert len(waits.due()) == 1  # entered again, waited again


def test_states_the_programs_own_monitors_leave_are_not_reported():
    clock = _Clock()
    waits = Waits(load_composition('approach_object'), after=5.0, clock=clock)
    for state in ('approach', 'hold', 'retreat'):
        _enter(waits, 'itasc', state)
        clock.now += 30.0
        assert waits.due() == []


def test_leaving_running_ends_the_wait():
    clock = _Clock()
    waits = Waits(load_composition('pick_with_gripper'), after=5.0, clock=clock)
    _enter(waits, 'itasc', 'wait_for_gripper')
    waits.on_transition(Transition(composite='itasc', state='Safety', event='e_emergency', stamp=0.0))
    clock.now += 10.0
    assert waits.due() == []


def test_the_command_names_a_nested_field_and_a_relative_name_in_the_composites_namespace():
    from itasc_bringup.console.waiting import how_to_raise
    plc = OutsideEventModel(event='e_part_present', topic='plc/status', type='example/msg/Status',
                            field='inputs.part', value='present')
    assert how_to_raise(plc, namespace='/cell/itasc') == (
        "ros2 topic pub --once /cell/itasc/plc/status example/msg/Status \"{inputs: {part: 'present'}}\"")

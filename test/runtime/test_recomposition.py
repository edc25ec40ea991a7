"""Run-time re-composition with real rclpy nodes over real DDS (paper §3.1: the Composer changes
the architecture while the composite runs; itasc_core.composition.steps): swap, remove, a step with
steps of children, and a step that does not fit, each judged by what the running composite does."""

from __future__ import annotations

import pytest

from hierarchy_harness import Hierarchy

STIFF = {'name': 'controller', 'kind': 'PController', 'parameters': {'kp': 9.0, 'max_output': 100.0}}
#: ports of another quantity: its setpoint input does not fit the setpoint generator's output
WRONG = {'name': 'controller', 'kind': 'PController', 'parameters': {'semantics': 'Position(y)'}}


def task(name: str, kp: float) -> dict:
    return {'name': name, 'entities': [
        {'name': 'setpoint', 'kind': 'SineSource', 'parameters': {'amplitude': 1.0, 'frequency': 2.0}},
        {'name': 'controller', 'kind': 'PController', 'parameters': {'kp': kp, 'max_output': 100.0}},
    ], 'connections': [{'from': 'setpoint.signal', 'to': 'controller.setpoint'}],
        'exports': {'command': 'controller.command', 'measured': 'controller.measured'},
        'composition_steps': {'stiff': {'swap': [STIFF]}, 'wrong': {'swap': [WRONG]}}}


def model() -> dict:
    program = {'name': 'program', 'entities': [task('track', 2.0), task('hold', 0.5), {'name': 'mixer', 'kind': 'Sum'}],
               'connections': [{'from': 'track.command', 'to': 'mixer.inputs'},
                               {'from': 'hold.command', 'to': 'mixer.inputs'}],
               'exports': {'command': 'mixer.sum', 'measured_track': 'track.measured'},
               'composition_steps': {'alone': {'remove': ['hold']},
                                     'alone_and_stiff': {'remove': ['hold'], 'children': {'track': 'stiff'}},
                                     'alone_and_wrong': {'remove': ['hold'], 'children': {'track': 'wrong'}}}}
    return {'name': 'root', 'rate': 200, 'entities': [program, {'name': 'plant', 'kind': 'Integrator'}],
            'connections': [{'from': 'program.command', 'to': 'plant.rate'},
                            {'from': 'plant.state', 'to': 'program.measured_track'}]}


@pytest.fixture
def running():
    h = Hierarchy(model())
    h.listen('/root/program')
    h.listen('/root/program/track')
    h.start()
    assert h.spin_until(lambda: all(h.coordinators.get(c) is not None and h.state(c) == 'Active.Run.Running'
                                    for c in ('root', 'program', 'track', 'hold')))
    yield h
    h.close()


def composer(h: Hierarchy, *path: str):
    c = h.composer
    for name in path:
        c = c.children[name]
    return c


def answer(h: Hierarchy, composite: str, step: str):
    """The Composer's answer to ``step``: e_<composite>_composed or _compose_failed."""
    names = (f'e_{composite}_composed', f'e_{composite}_compose_failed')
    found = lambda: [e for e in h.events if e.name in names and e.detail.startswith(f'{step}:')]  # noqa: E731
    assert h.spin_until(lambda: found(), timeout=20), [(e.name, e.detail) for e in h.events]
    return found()[0]


def node_names(h: Hierarchy) -> set[str]:
    return {f'{ns.rstrip("/")}/{name}' for name, ns in h.node.get_node_names_and_namespaces()}


def test_a_swapped_controller_computes_with_its_own_gain_from_the_next_tick_in_the_old_ones_place(running):
    h = running
    track = composer(h, 'program', 'track')
    old = track.entities['controller']
    order = track.scheduler.order
    h.raise_event('e_track_compose_stiff', '/root/program/track')
    done = answer(h, 'track', 'stiff')
    assert done.name == 'e_track_composed' and done.detail == 'stiff: swapped controller', done.detail
    new = track.entities['controller']
    assert new is not old and new.get_parameter('kp').value == 9.0
    assert track.scheduler.order == order  # at its place
    ticks = track.scheduler.ticks
    assert h.spin_until(lambda: track.scheduler.ticks >= ticks + 3, timeout=5)
    # what its gain predicts, on what it received: command = kp * (setpoint - measured)
    error, command = new.outputs['error'].last.data, new.outputs['command'].last.data
    assert command[0] == pytest.approx(9.0 * error[0], rel=1e-12) and abs(error[0]) > 1e-6
    # the mixer of the program (the parent) gets the new controller's command on the same topic
    mixer = composer(h, 'program').entities['mixer']
    assert mixer.inputs['inputs'].samples['/root/program/track/controller/command'] is new.outputs['command'].last
    # the old one is gone from the ROS graph, the composite still runs
    assert h.spin_until(lambda: len([n for n in node_names(h) if n == '/root/program/track/controller']) == 1)
    assert h.state('track') == 'Active.Run.Running' and h.state('program') == 'Active.Run.Running'


def test_a_swap_whose_ports_do_not_fit_is_refused_and_nothing_changes(running):
    h = running
    track = composer(h, 'program', 'track')
    old, history = track.entities['controller'], list(h.coordinators['track'].history)
    h.raise_event('e_track_compose_wrong', '/root/program/track')
    refused = answer(h, 'track', 'wrong')
    assert refused.name == 'e_track_compose_failed'
    assert "semantics 'Position(x)' != 'Position(y)'" in refused.detail, refused.detail
    assert track.entities['controller'] is old and old.outputs['command'].topic in {
        p.topic for p in old.outputs.values()}
    ticks = track.scheduler.ticks
    assert h.spin_until(lambda: track.scheduler.ticks >= ticks + 5, timeout=5)  # it keeps computing
    assert h.coordinators['track'].history == history  # and never left Running
    assert h.spin_for(0.3) is None and len([n for n in node_names(h) if n.endswith('/track/controller')]) == 1


def test_a_removed_task_stops_in_order_leaves_the_graph_and_the_mixer_while_the_rest_runs_on(running):
    h = running
    program = composer(h, 'program')
    hold_nodes = {n for n in node_names(h) if n.startswith('/root/program/hold/')}
    assert {'/root/program/hold/coordinator', '/root/program/hold/controller'} <= hold_nodes
    h.raise_event('e_program_compose_alone', '/root/program')
    assert answer(h, 'program', 'alone').detail == 'alone: removed hold'
    mixer = program.entities['mixer'].inputs['inputs']
    assert list(mixer.samples) == ['/root/program/track/controller/command']  # at once
    assert h.spin_until(lambda: h.states('hold')[-1] == 'Active.Stop.Stopped.NotifyStopped')
    assert h.spin_until(lambda: not {n for n in node_names(h) if n.startswith('/root/program/hold/')}, timeout=10), \
        {n for n in node_names(h) if n.startswith('/root/program/hold/')}
    assert 'hold' not in program.children and 'hold' not in h.coordinators['program'].fsm.children
    assert h.state('program') == 'Active.Run.Running' and h.state('track') == 'Active.Run.Running'
    # and the program still stops in order, without waiting for the removed task
    h.raise_event('e_root_stop')
    assert h.spin_until(lambda: h.state('root').endswith('NotifyStopped'))


def test_a_step_with_a_step_of_a_child_does_both_or_nothing_of_its_own(running):
    h = running
    program, track = composer(h, 'program'), composer(h, 'program', 'track')
    h.raise_event('e_program_compose_alone_and_wrong', '/root/program')
    refused = answer(h, 'program', 'alone_and_wrong')
    assert refused.name == 'e_program_compose_failed'
    assert 'track: ' in refused.detail and 'Position(y)' in refused.detail
    assert 'hold' in program.children and len(program.entities['mixer'].inputs['inputs'].sources) == 2
    h.raise_event('e_program_compose_alone_and_stiff', '/root/program')
    done = answer(h, 'program', 'alone_and_stiff')
    assert done.name == 'e_program_composed' and done.detail == 'alone_and_stiff: removed hold; children track:stiff'
    assert track.entities['controller'].get_parameter('kp').value == 9.0
    assert program.entities['mixer'].inputs['inputs'].sources == ['/root/program/track/controller/command']
    assert h.spin_until(lambda: 'hold' not in program.children)  # once it stopped

"""Operating a running application: re-composition and parameters (issue #14 items 2 and 4; paper
§3.1: the Composer changes the architecture while the composite runs; §5: a parameter change is
configuration; README "Operating a running application"), proven by effect, through clients in
another process, as ``ros2 service call`` and ``ros2 param set`` would.

``pick_and_retreat``: entering ``retreat`` runs the composition step ``retreat``, which removes
AvoidObstacle and swaps ApproachObject's controller and setpoint generator. From a recorded tick on
the Solver's problem has one task fewer, the removed task's nodes, publishers and parameters are
gone from the ROS graph, the new controller's output is what its gains predict, and the commanded
velocity goes on without a jump. A swap to an entity whose ports do not fit (a step the test adds to
the same structure, which no iTaSC model can express) is refused with ``e_ApproachObject_compose_failed``
and changes nothing. Then the new controller's gain is set from outside: its output follows the new
gain from the next tick, the change is in the recording, an out-of-range gain is refused with the
model's range and changes nothing, and the dump of the running entities is a named
configuration the model takes.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import yaml
from processes import Spawned
from recordings import read_recording
from ros_client import call_service, call_services, get_parameter, ros_node, spin_until

from rcl_interfaces.msg import SetParametersResult
from rcl_interfaces.srv import GetParameters, ListParameters, SetParameters
from rclpy.parameter import Parameter, parameter_value_to_python
from std_srvs.srv import Trigger

from itasc_core.computation.parameters import nest
from itasc_msgs.srv import Compose

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'bench'))
from bench_recompose import model as steps_model  # pick_and_retreat with steps alone and back

BOOTSTRAP = [sys.executable, '-m', 'itasc_bringup.bootstrap']
ROOT = '/pick_and_retreat'
PROGRAM = f'{ROOT}/itasc'
TASK = f'{PROGRAM}/ApproachObject'
REMOVED = f'{PROGRAM}/AvoidObstacle'
#: The Task's Configurator: it serves the parameters of the Task's entities (``CC.kp``).
CONFIGURATOR = f'{TASK}/configurator'
#: The swapped-in controller of the model (config/programs/pick_and_retreat.yaml).
KP, MAX_OUTPUT = 1.0, 0.1
#: The gain set from outside while it retreats.
NEW_KP = 2.0


def model_with_a_step_that_does_not_fit(tmp_path: Path) -> Path:
    """The composition model of pick_and_retreat, written out, with one more step of ApproachObject:
    a controller of another Task (its ports carry ``Output(AvoidObstacle)``). Infinite parameter
    values are written as ±1e300 (a model file holds finite numbers only)."""
    from itasc_bringup.apps import load_composition, write_composition

    data = load_composition('pick_and_retreat').model_dump(by_alias=True, exclude_defaults=True)
    program = next(e for e in data['entities'] if e['name'] == 'itasc')
    task = next(e for e in program['entities'] if e['name'] == 'ApproachObject')
    controller = next(e for e in task['entities'] if e['name'] == 'CC')
    task['composition_steps']['other_task'] = {'swap': [
        {**controller, 'parameters': {**controller['parameters'], 'task': 'AvoidObstacle'}}]}
    return write_composition(data, tmp_path / 'pick_and_retreat.yaml')


def compose(composite: str, step: str) -> Compose.Response:
    return call_service(Compose, f'{composite}/coordinator/compose', Compose.Request(step=step))


def trigger(service: str) -> Trigger.Response:
    return call_service(Trigger, service, Trigger.Request())


def graph_under(namespace: str) -> dict[str, list[str]]:
    """What of ``namespace`` the ROS graph holds: nodes, topics someone publishes, services."""
    with ros_node() as (node, executor):
        # discovered the application (its root Coordinator), and a while to hear of everything else
        names = lambda: [f'{ns.rstrip("/")}/{n}' for n, ns in node.get_node_names_and_namespaces()]  # noqa: E731
        assert spin_until(executor, lambda: f'{ROOT}/coordinator' in names(), timeout=20)
        spin_until(executor, lambda: False, timeout=1.0)
        nodes = names()
        topics = [t for t, _ in node.get_topic_names_and_types() if node.get_publishers_info_by_topic(t)]
        services = [s for s, _ in node.get_service_names_and_types()]
    inside = lambda names: sorted(n for n in names if n.startswith(namespace + '/'))  # noqa: E731
    return {'nodes': inside(nodes), 'topics': inside(topics), 'services': inside(services)}


def by_stamp(messages) -> dict[float, object]:
    return {m.stamp.sec + m.stamp.nanosec * 1e-9: m for m in messages}


@dataclass
class Session:
    """What one run of pick_and_retreat did and answered (the tests judge it)."""

    mcap: Path
    dump: Path
    graph_before: dict[str, list[str]]
    graph_after: dict[str, list[str]]
    refused_swap: Compose.Response
    unknown_step: Compose.Response
    controller_before: dict[str, object]
    controller_after: dict[str, object]
    set_gain: SetParametersResult
    refused_gain: SetParametersResult
    gain_after_refusal: float


def set_parameter(node_name: str, name: str, value: float) -> SetParametersResult:
    """``ros2 param set <node> <name> <value>``."""
    request = SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()])
    return call_service(SetParameters, f'{node_name}/set_parameters', request).results[0]


def dump_parameters(node_names: list[str], path: Path) -> None:
    """What ``ros2 param dump`` writes for ``node_names``: node -> ros__parameters, dotted names nested."""
    listed = [r.result.names for r in call_services(
        [(ListParameters, f'{name}/list_parameters', ListParameters.Request()) for name in node_names])]
    values = [r.values for r in call_services(
        [(GetParameters, f'{name}/get_parameters', GetParameters.Request(names=list(names)))
         for name, names in zip(node_names, listed)])]
    dump = {name: {'ros__parameters': nest({n: parameter_value_to_python(v) for n, v in zip(names, vs)})}
            for name, names, vs in zip(node_names, listed, values)}
    path.write_text(yaml.safe_dump(dump))


@pytest.fixture(scope='module')
def session(tmp_path_factory) -> Session:
    tmp = tmp_path_factory.mktemp('retreat')
    mcap = tmp / 'retreat.mcap'
    with Spawned([*BOOTSTRAP, str(model_with_a_step_that_does_not_fit(tmp)), '-v', '--record', str(mcap)]) as app:
        app.wait_for_line('[state] itasc: Active.Run.Running.wait_for_gripper', timeout=120)
        graph_before = graph_under(REMOVED)
        refused_swap = compose(TASK, 'other_task')  # a swap whose ports do not fit
        controller_before = {n: get_parameter(CONFIGURATOR, f'CC.{n}') for n in ('task', 'kind')}
        unknown_step = compose(PROGRAM, 'no_such_step')
        said = trigger(f'{PROGRAM}/object_grasped')  # the gripper holds the object
        assert said.success, said
        app.wait_for_line('[state] itasc: Active.Run.Running.retreating', timeout=30)
        app.wait_for_line('[state] itasc: Active.Run.Running.away', timeout=30)
        controller_after = {n: get_parameter(CONFIGURATOR, f'CC.{n}') for n in ('kind', 'kp')}
        graph_after = graph_under(REMOVED)
        time.sleep(0.5)
        set_gain = set_parameter(CONFIGURATOR, 'CC.kp', NEW_KP)  # ros2 param set .../configurator CC.kp 2.0
        time.sleep(0.5)
        refused_gain = set_parameter(CONFIGURATOR, 'CC.kp', -1.0)
        time.sleep(0.5)
        gain_after_refusal = get_parameter(CONFIGURATOR, 'CC.kp')
        dump_parameters([CONFIGURATOR], tmp / 'dump.yaml')
        stop = trigger(f'{ROOT}/coordinator/stop')
        assert stop.success, stop
        assert app.finish(timeout=60) == 0, app.output()
    return Session(mcap, tmp / 'dump.yaml', graph_before, graph_after, refused_swap, unknown_step, controller_before,
                   controller_after, set_gain, refused_gain, gain_after_refusal)


def test_entering_retreat_removes_a_task_and_swaps_a_controller_between_two_ticks(session):
    before, after = session.graph_before, session.graph_after
    assert f'{REMOVED}/CC' in before['nodes'] and f'{REMOVED}/Rows/rows' in before['topics'], before
    assert f'{REMOVED}/configurator/set_parameters' in before['services'], before
    assert after == {'nodes': [], 'topics': [], 'services': []}, after
    # the swap whose ports do not fit was refused and changed nothing
    assert not session.refused_swap.success, session.refused_swap
    assert "semantics 'Output(ApproachObject)' != 'Output(AvoidObstacle)'" in session.refused_swap.message
    assert session.controller_before == {'task': 'ApproachObject', 'kind': 'pid'}
    assert not session.unknown_step.success and 'steps: retreat' in session.unknown_step.message
    assert session.controller_after == {'kind': 'p', 'kp': KP}

    run = read_recording(session.mcap)
    program_events = run[f'{PROGRAM}/events']
    task_events = run[f'{TASK}/events']
    failed = [m for m in task_events if m.name == 'e_ApproachObject_compose_failed']
    assert len(failed) == 1 and failed[0].detail.startswith('other_task: ') and failed[0].source == f'{TASK}/composer'
    # the answers of the program's step and of its Task's part, recorded on the program's topic
    composed = {m.name: m for m in program_events if m.name in ('e_itasc_composed', 'e_ApproachObject_composed')}
    assert composed['e_ApproachObject_composed'].detail == 'retreat: swapped CC, SPG'
    assert composed['e_itasc_composed'].detail == 'retreat: removed AvoidObstacle; children ApproachObject:retreat'
    asked = next(m for m in program_events if m.name == 'e_itasc_compose_retreat')
    states = [m.state for m in run[f'{PROGRAM}/state']]
    assert states[-1] == 'Active.Stop.Stopped.NotifyStopped'
    assert [m.state for m in run[f'{REMOVED}/state']][-1] == 'Active.Stop.Stopped.NotifyStopped'  # in order

    # the Solver's problem has one task fewer from a recorded tick on
    status = run[f'{PROGRAM}/Solver/status']
    tasks = [sorted(m.active_tasks) for m in status]
    stopping = next(m._sent for m in run[f'{PROGRAM}/state'] if m.state == 'Active.Stop.Stopping')
    first = next(k for k, t in enumerate(tasks) if t == ['ApproachObject'] and status[k]._sent > asked._sent)
    assert all(t == ['ApproachObject', 'AvoidObstacle'] for t in tasks[first - 20:first]), tasks[first - 20:first]
    running = [t for t, m in zip(tasks[first:], status[first:]) if m._sent < stopping]
    assert len(running) > 100 and all(t == ['ApproachObject'] for t in running), set(map(tuple, running))
    assert not [m for m in run[f'{REMOVED}/Rows/rows'] if m._sent > status[first]._sent]

    # the new controller's output is what its gains predict: desired = sat(kp e) once its setpoint
    # motion is over (no feed-forward), on every tick of 'away' until its gain was set from outside
    away = next(m._sent for m in run[f'{PROGRAM}/state'] if m.state == 'Active.Run.Running.away')
    gain_set = next(m._sent for m in task_events if m.name == 'e_CC_parameter_set' and m._sent > away)
    desired, error = control(run, after=away, until=gain_set)
    assert len(desired) > 20, len(desired)
    assert np.abs(desired - np.clip(KP * error, -MAX_OUTPUT, MAX_OUTPUT)).max() < 1e-9
    assert np.abs(error).max() > 1e-5  # a test of the law, not of zeros
    assert np.abs(desired - 4.0 * error).max() > 1e-5  # not the gain the old controller had
    # its setpoint generator started anew from where the Task was: progress from 0, done 3 s later
    since = composed['e_ApproachObject_composed']._sent
    progress = [(m._sent, m.data) for m in run[f'{TASK}/SPG/progress'] if m._sent > since]
    assert progress[0][1] < 0.05, progress[:3]
    done = next(sent for sent, p in progress if p >= 1.0)
    assert 2.5 < done - progress[0][0] < 4.5

    # the commanded velocity goes on without a jump: at each switch (the first ticks after the swap and
    # after the removal) no joint's command changes more from one tick to the next than it does
    # while the robot approaches, and never beyond the velocity limits
    command = run[f'{PROGRAM}/Solver/command']
    sent = np.array([m._sent for m in command])
    qdot = np.array([m.velocity for m in command])
    change = np.abs(np.diff(qdot, axis=0)).max(axis=1)  # change[k]: from tick k to tick k + 1
    entered = {m.state.rsplit('.', 1)[-1]: m._sent for m in run[f'{PROGRAM}/state']}
    approach = change[(sent[1:] > entered['approach'] + 0.5) & (sent[1:] < entered['wait_for_gripper'])]
    switch = []
    for at in (composed['e_ApproachObject_composed']._sent, status[first]._sent):
        k = int(np.searchsorted(sent, at))  # the first tick after the switch
        switch += list(change[k - 3:k + 3])
    assert len(approach) > 100, len(approach)
    assert max(switch) <= approach.max(), (switch, approach.max())
    limits = np.array(get_limits())
    assert (np.abs(qdot) <= limits + 1e-9).all()


def control(run: dict, *, after: float, until: float = math.inf) -> tuple[np.ndarray, np.ndarray]:
    """What ApproachObject's controller asked (its rows' desired output velocities) and the error it
    saw (its state), tick by tick, for the ticks recorded between ``after`` and ``until``."""
    rows, state = by_stamp(run[f'{TASK}/Rows/rows']), by_stamp(run[f'{TASK}/Rows/state'])
    ticks = sorted(t for t, m in rows.items() if after < m._sent < until and t in state)
    return np.array([rows[t].desired for t in ticks]), np.array([state[t].error for t in ticks])


def test_a_gain_set_from_outside_drives_the_next_tick_is_recorded_and_a_wrong_one_changes_nothing(session):
    assert session.set_gain.successful, session.set_gain
    assert not session.refused_gain.successful
    assert session.refused_gain.reason == 'Parameter kp out of range Min: 0.0, Max: inf, value: -1.0', \
        session.refused_gain.reason
    assert session.gain_after_refusal == NEW_KP
    run = read_recording(session.mcap)
    events = run[f'{TASK}/events']
    # the recording holds the change: the entity, the parameter, the old and the new value, who
    (changed,) = [m for m in events if m.name == 'e_CC_parameter_set' and m.detail.endswith('(set from outside)')]
    assert changed.source == f'{TASK}/CC' and changed.detail == f'kp: {KP} -> {NEW_KP} (set from outside)'
    (refused,) = [m for m in events if m.name == 'e_CC_parameter_refused']
    assert refused.source == f'{TASK}/CC'
    assert refused.detail == f'kp = -1.0: {session.refused_gain.reason} (set from outside)', refused.detail
    # the configuration the Task's Configurator applied is recorded as such
    assert any(m.name == 'e_CC_parameter_set' and m.detail.endswith('(configuration high_accuracy_control)')
               for m in events)
    # from the next tick on the controller's output is what the new gain predicts, and stays so
    # after the refused value
    stopping = next(m._sent for m in run[f'{PROGRAM}/state'] if m.state == 'Active.Stop.Stopping')
    before, error_before = control(run, after=changed._sent - 0.3, until=changed._sent)
    desired, error = control(run, after=changed._sent, until=stopping)
    assert len(before) > 5 and len(desired) > 50, (len(before), len(desired))
    assert np.abs(before - np.clip(KP * error_before, -MAX_OUTPUT, MAX_OUTPUT)).max() < 1e-9
    assert np.abs(desired - np.clip(NEW_KP * error, -MAX_OUTPUT, MAX_OUTPUT)).max() < 1e-9
    assert np.abs(error).max() > 1e-6


def test_the_dump_of_the_running_entities_is_a_named_configuration_of_the_model(session, tmp_path):
    """``ros2 param dump`` of the running controller and rows, turned by ``itasc-model configuration``
    into a named configuration, is taken by the model and sets what was running."""
    import shutil
    import subprocess

    from itasc_bringup.apps import load_composition
    made = subprocess.run([sys.executable, '-m', 'itasc_bringup.model.cli', 'configuration', str(session.dump),
                           '--name', 'tuned'], capture_output=True, text=True, timeout=60)
    assert made.returncode == 0, made.stderr
    snippet = yaml.safe_load(made.stdout)
    assert snippet['configurations']['tuned']['ApproachObject']['controller']['kp'] == NEW_KP
    config = tmp_path / 'config'
    shutil.copytree(Path(__file__).resolve().parents[1] / 'config', config)
    program = config / 'programs' / 'pick_and_retreat.yaml'
    model = yaml.safe_load(program.read_text())
    model['configurations'].update(snippet['configurations'])
    program.write_text(yaml.safe_dump(model, sort_keys=False))
    task = load_composition(str(config / 'apps' / 'pick_and_retreat.yaml')).entity('itasc').entity('ApproachObject')
    tuned = task.configurations['tuned']
    assert tuned['CC']['kp'] == NEW_KP and tuned['CC']['max_output'] == MAX_OUTPUT
    assert tuned['Rows'] == {'weights': [1.0, 1.0, 1.0, 0.5, 0.5, 0.5], 'priority': 1}


def get_limits() -> list[float]:
    from itasc_bringup.apps import load_composition

    solver = load_composition('pick_and_retreat').entity('itasc').entity('Solver')
    return solver.parameters['velocity_limit']


def test_a_task_composite_removed_and_added_back_runs_again_in_a_process_of_its_own(tmp_path):
    """``--deploy per-composite``: the step ``back`` starts a new process for AvoidObstacle soon after
    ``alone`` stopped the old one (whose endpoints linger a moment in the graph): it is answered,
    the new process's Task reaches Running, and the application still stops in order."""
    with Spawned([*BOOTSTRAP, str(steps_model(tmp_path)), '--deploy', 'per-composite', '-v']) as app:
        app.wait_for_line('[state] itasc: Active.Run.Running.wait_for_gripper', timeout=120)
        removed = compose(PROGRAM, 'alone')
        assert removed.success, removed
        app.wait_for_line('[state] AvoidObstacle: Active.Stop.Stopped.NotifyStopped', timeout=30)
        added = compose(PROGRAM, 'back')
        assert added.success, added
        app.wait_for_line('[state] AvoidObstacle: Active.Run.Running', timeout=30)
        stop = trigger(f'{ROOT}/coordinator/stop')
        assert stop.success, stop
        assert app.finish(timeout=60) == 0, app.output()


def test_a_step_its_state_runs_that_fails_is_said_while_it_runs():
    """An operator ran ``retreat`` ahead of the program; entering its own ``retreat`` state, the
    program ran the step again, which fails (AvoidObstacle is gone), and it waits for an
    ``e_itasc_composed`` that cannot come. Before, nothing but an ERROR log line said so while it
    ran; now the console says the failed step as it happens, with why."""
    with Spawned([*BOOTSTRAP, 'pick_and_retreat', '--duration', '30']) as app:
        app.wait_for_line('[state] itasc: Active.Run.Running.wait_for_gripper', timeout=120)
        ahead = compose(PROGRAM, 'retreat')
        assert ahead.success, ahead
        assert trigger(f'{PROGRAM}/object_grasped').success
        line = app.wait_for_line(f'warning: e_itasc_compose_failed from {PROGRAM}/composer: retreat: ', timeout=30)
        assert 'AvoidObstacle' in line, line
        stop = trigger(f'{ROOT}/coordinator/stop')
        assert stop.success, stop
        assert app.finish(timeout=60) == 0, app.output()

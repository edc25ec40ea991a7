"""Operating a running application from ROS (issue #14 items 1 and 3; paper §6.1 Safety and its
recovery by reconfiguration; README "Operating a running application"), proven by effect, through
a real client in another process, as ``ros2 service call`` would:

* every composite offers ``<ns>/coordinator/{raise_event,recover,stop}``;
* ``~/recover`` is refused while a driver is still silent, saying so; once it is back, it brings
  the root to Running again, and the robot converges on its task again (measured on the recorded
  joint states); no event is lost and the recording tells the whole story; exit 4;
* an outside event (a separate gripper node's ``std_msgs/Bool``) moves the Running sub-FSM on, only
  after it came;
* ``~/stop`` of any composite, even one in a process of its own, ends the run in order: exit 0,
  complete recording.
"""

from __future__ import annotations

import sys
import time
from collections import defaultdict
from pathlib import Path

import numpy as np
from model_files import app_with_drivers
from processes import Spawned
from recordings import read_recording
from ros_client import call_service, ros_node

from std_srvs.srv import Trigger

from itasc_msgs.srv import RaiseEvent

BOOTSTRAP = [sys.executable, '-m', 'itasc_bringup.bootstrap']
FAKE_ROS2_CONTROL = [sys.executable, '-m', 'itasc_drivers.fake_ros2_control']
GRIPPER = [sys.executable, str(Path(__file__).parent / 'support' / 'gripper.py')]
FINAL = 'Active.Stop.Stopped.NotifyStopped'


def trigger(service: str, *, timeout: float = 30.0) -> Trigger.Response:
    return call_service(Trigger, service, Trigger.Request(), timeout=timeout)


def raise_event(service: str, name: str) -> RaiseEvent.Response:
    return call_service(RaiseEvent, service, RaiseEvent.Request(name=name))


def composites_of(app: str) -> dict[str, bool]:
    """The namespace of every composite of ``app``, and whether its model has composition steps."""
    from itasc_bringup.apps import load_composition
    from itasc_core.composition.model import walk
    return {path: bool(model.composition_steps) for path, model in walk(load_composition(app))}


def assert_operator_services(composites: dict[str, bool], *, timeout: float = 30.0) -> None:
    """Every composite lists its operator services with their types (``ros2 service list -t``),
    ``~/compose`` only where its model has composition steps (a service elsewhere would refuse
    every call, and each service is a DDS reader and writer every endpoint of its process pairs with)."""
    expected = {f'{ns}/coordinator/{name}': [kind] for ns, steps in composites.items() for name, kind in (
        ('raise_event', 'itasc_msgs/srv/RaiseEvent'), ('recover', 'std_srvs/srv/Trigger'),
        ('stop', 'std_srvs/srv/Trigger'), *([('compose', 'itasc_msgs/srv/Compose')] if steps else []))}
    without = {f'{ns}/coordinator/compose' for ns, steps in composites.items() if not steps}
    with ros_node() as (node, executor):
        deadline = time.monotonic() + timeout
        while True:
            listed = dict(node.get_service_names_and_types())
            missing = {name: kind for name, kind in expected.items() if listed.get(name) != kind}
            if not missing or time.monotonic() > deadline:
                break
            executor.spin_once(timeout_sec=0.1)
    assert not missing, f'not listed (or of another type): {missing}'
    assert not without & set(listed), f'offered by a composite without composition steps: {without & set(listed)}'


def assert_no_event_lost(run: dict[str, list]) -> None:
    """Per event topic and source, the sequence numbers run 1, 2, 3, ... without a gap."""
    for topic, messages in run.items():
        if not topic.endswith('/events'):
            continue
        by_source: dict[str, list[int]] = defaultdict(list)
        for msg in messages:
            by_source[msg.source].append(msg.seq)
        for source, seqs in by_source.items():
            assert sorted(seqs) == list(range(1, len(seqs) + 1)), (topic, source, seqs[:5], len(seqs))


def states(run: dict[str, list], namespace: str) -> list:
    return run[f'{namespace}/state']


def events(run: dict[str, list], namespace: str, name: str) -> list:
    return [m for m in run[f'{namespace}/events'] if m.name == name]


# -- recovery from Safety ------------------------------------------------------------------------------

def tcp_errors(run: dict[str, list], *, after: float, until: float) -> np.ndarray:
    """Distance [m] of the TCP from the object's grasp frame at every recorded joint state of the
    driver sent between ``after`` and ``until``: forward kinematics of the model's Panda."""
    import pinocchio as pin
    from itasc_bringup.model import load_application
    from itasc_core.itasc.robot import Robot

    app = load_application('config/apps/approach_object_ros_driver.yaml')
    robot_model = app.program.robots[0]
    robot = Robot('panda', robot_model.urdf)
    tcp = next(f for f in robot_model.frames if f.name == 'tcp')
    target = next(o for o in app.program.objects if o.name == 'target')
    grasp = next(f for f in target.frames if f.name == 'grasp')
    world_target = pin.SE3(pin.rpy.rpyToMatrix(*target.rpy), np.array(target.xyz))
    world_grasp = world_target * pin.SE3(pin.rpy.rpyToMatrix(*grasp.rpy), np.array(grasp.xyz))
    link_tcp = pin.SE3(pin.rpy.rpyToMatrix(*tcp.rpy), np.array(tcp.xyz))
    errors = []
    for msg in run['/approach_object_ros_driver/Driver_panda/joint_state']:
        if after <= msg._sent <= until:
            robot.set_positions(msg.name, msg.position)
            robot.update()
            errors.append(np.linalg.norm((robot.frame_pose(tcp.link) * link_tcp).translation - world_grasp.translation))
    return np.array(errors)


def test_recover_is_refused_while_the_driver_is_silent_and_brings_the_robot_back_once_it_is_back(tmp_path):
    root, mcap = '/approach_object_ros_driver', tmp_path / 'recovered.mcap'
    # silent for 1 s, not 0.25 s: the silence made here lasts seconds, and a stall of a loaded
    # machine (a parallel test run) must not be taken for it
    app_file = app_with_drivers('approach_object_ros_driver', tmp_path, silent_after=1.0)
    with Spawned(FAKE_ROS2_CONTROL) as driver, \
            Spawned([*BOOTSTRAP, str(app_file), '--record', str(mcap)]) as app:
        app.wait_for_line('[state] approach_object_ros_driver: Active.Run.Running', timeout=120)
        assert_operator_services(composites_of('approach_object_ros_driver'))
        time.sleep(1.0)
        before = app.forget_lines()  # the Safety awaited below must be the one the silence causes
        assert not any(line.startswith('SAFETY') for line in before), \
            'Safety before the driver fell silent (a watchdog saw a stall of this machine)\n' + app.output()
        driver.kill()  # the driver falls silent
        app.wait_for_line('SAFETY: approach_object_ros_driver entered Safety <- e_emergency from '
                          f'{root}/Driver_panda_silent', timeout=10)

        refused = trigger(f'{root}/coordinator/recover')
        assert not refused.success, refused
        assert 'still there' in refused.message and 'Driver_panda_silent' in refused.message \
            and 'stale' in refused.message, refused.message
        below = trigger(f'{root}/itasc/coordinator/recover')
        assert not below.success and 'because its parent is' in below.message, below
        assert not raise_event(f'{root}/itasc/coordinator/raise_event', 'e_no_such_event').success

        with Spawned(FAKE_ROS2_CONTROL) as driver_again:  # the driver comes back (from its start pose)
            deadline = time.monotonic() + 30
            while not (answer := trigger(f'{root}/coordinator/recover')).success:
                assert 'Driver_panda_silent' in answer.message and time.monotonic() < deadline, answer
                time.sleep(0.5)
            assert 'Running' in answer.message, answer
            # the robot converges on the task again: the Monitor sees it converged (hold -> retreat)
            app.wait_for_line('[state] itasc: Active.Run.Running.retreat', timeout=90)
            stop = trigger(f'{root}/itasc/coordinator/stop')  # from a composite below the root
            assert stop.success, stop
            assert app.finish(timeout=60) == 4, app.output()
            assert driver_again.process.poll() is None
    assert 'went through Safety, recovered) - exit 4' in app.out.splitlines()[-1], app.output()

    run = read_recording(mcap)
    assert_no_event_lost(run)
    story = [m.state for m in states(run, root)]
    safety = story.index('Safety')
    assert 'Active.Run.Running' in story[:safety]
    after = story[safety + 1:]
    assert after[0] == 'Active.Configure.Configuring.DeployEntities', after
    assert 'Active.Run.Running' in after and after[-1] == FINAL, after
    assert after.index('Active.Run.Running') < after.index('Active.Stop.Stopping')
    itasc = [m.state for m in states(run, f'{root}/itasc')]
    assert itasc.index('Safety') < itasc.index('Active.Run.Running.retreat') and itasc[-1] == FINAL, itasc
    # why it went to Safety, why the first recovery was refused, what the accepted one left behind
    assert any('Driver_panda_silent' in m.source for m in events(run, root, 'e_emergency'))
    checked = events(run, root, 'e_approach_object_ros_driver_faults_checked')
    assert 'stale' in checked[0].detail and checked[-1].detail.endswith('|'), [m.detail for m in checked]
    recovering = events(run, root, 'e_approach_object_ros_driver_recovering')
    assert len(recovering) == 1 and 'Driver_panda_silent' in recovering[0].detail
    assert events(run, f'{root}/itasc', 'e_stop_requested') or events(run, root, 'e_stop_requested')

    # measured on the recorded joint states: back from the driver's start pose onto the grasp frame
    running_again = next(m._sent for m in states(run, root)[safety:] if m.state == 'Active.Run.Running')
    retreat = next(m._sent for m in states(run, f'{root}/itasc') if m.state == 'Active.Run.Running.retreat')
    errors = tcp_errors(run, after=running_again, until=retreat)
    assert len(errors) > 100, len(errors)
    assert errors[0] > 0.1, errors[0]  # it started from afar
    assert errors[-1] < 2e-3, errors[-1]  # and converged


# -- outside events -------------------------------------------------------------------------------------

def test_a_gripper_node_moves_the_running_sub_fsm_on_only_when_it_says_grasped_and_stop_ends_the_run(tmp_path):
    root, mcap, false_for = '/pick_with_gripper', tmp_path / 'pick.mcap', 1.5
    with Spawned([*BOOTSTRAP, 'pick_with_gripper', '--record', str(mcap)]) as app:
        app.wait_for_line('[state] itasc: Active.Run.Running.wait_for_gripper', timeout=120)
        assert_operator_services(composites_of('pick_with_gripper'))
        refused = raise_event(f'{root}/itasc/coordinator/raise_event', 'e_nope')
        assert not refused.success and "reacts to 'e_nope'" in refused.message, refused
        not_in_safety = trigger(f'{root}/coordinator/recover')
        assert not not_in_safety.success and 'not in Safety' in not_in_safety.message, not_in_safety
        with Spawned([*GRIPPER, '--false-for', str(false_for)]) as gripper:
            true_from = float(gripper.wait_for_line('true from ', timeout=30).split()[-1])
            app.wait_for_line('[state] itasc: Active.Run.Running.retreat', timeout=30)
            time.sleep(1.0)  # it keeps saying true
            gripper.send_signal(2)
            gripper.finish(timeout=10)
        # the other way a PLC bridge says it: a std_srvs/Trigger call (no transition left to take)
        said = trigger(f'{root}/itasc/object_grasped')
        assert said.success and 'e_object_grasped' in said.message, said
        stop = trigger(f'{root}/coordinator/stop')
        assert stop.success, stop
        assert app.finish(timeout=60) == 0, app.output()
    assert app.out.splitlines()[-1].startswith(f'pick_with_gripper: stopped (~/stop: {root}/coordinator/stop) - exit 0')

    run = read_recording(mcap)
    assert_no_event_lost(run)
    for namespace in composites_of('pick_with_gripper'):
        assert states(run, namespace)[-1].state == FINAL, namespace
    program = states(run, f'{root}/itasc')
    waiting = next(m for m in program if m.state == 'Active.Run.Running.wait_for_gripper')
    retreat = next(m for m in program if m.state == 'Active.Run.Running.retreat')
    assert retreat.event == 'e_object_grasped'
    grasped = events(run, f'{root}/itasc', 'e_object_grasped')
    # the gripper said true ten times a second: one event; the service call: the second
    assert len(grasped) == 2, [(m.source, m.detail) for m in grasped]
    assert grasped[0].source == f'{root}/itasc/outside_events' and 'data=True' in grasped[0].detail
    assert grasped[1].detail == 'object_grasped'
    # it moved on only after the gripper said grasped, and waited all the while it said not
    assert true_from - 0.01 <= grasped[0]._sent <= retreat._sent, (true_from, grasped[0]._sent, retreat._sent)
    assert retreat._sent - waiting._sent >= false_for


# -- ~/stop from a composite in a process of its own ----------------------------------------------------

def test_stop_of_a_composite_in_its_own_process_stops_the_whole_hierarchy_in_order(tmp_path):
    mcap = tmp_path / 'stop.mcap'
    with Spawned([*BOOTSTRAP, 'pattern_demo', '--deploy', 'per-composite', '--record', str(mcap)]) as app:
        app.wait_for_line('[state] app: Active.Run.Running', timeout=120)
        assert_operator_services(composites_of('pattern_demo'))
        stop = trigger('/app/program/track/coordinator/stop')
        assert stop.success, stop
        assert app.finish(timeout=60) == 0, app.output()
    assert 'app: stopped (~/stop: /app/program/track/coordinator/stop) - exit 0' in app.out, app.output()
    run = read_recording(mcap)
    assert_no_event_lost(run)
    for namespace in composites_of('pattern_demo'):
        assert states(run, namespace)[-1].state == FINAL, namespace
    # the request travelled up, Coordinator to parent Coordinator
    assert [m.source for m in events(run, '/app/program', 'e_stop_requested')] == ['/app/program/track/coordinator']
    assert [m.source for m in events(run, '/app', 'e_stop_requested')] == ['/app/program/coordinator']

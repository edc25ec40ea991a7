"""The shipped applications end to end, as a user runs them: ``bootstrap <app> --record``, then
the recording read back with rosbags (no ROS needed to read it)."""

from __future__ import annotations

import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
from processes import Spawned
from rosbags.highlevel import AnyReader

BOOTSTRAP = [sys.executable, '-m', 'itasc_bringup.bootstrap']
FAKE_ROS2_CONTROL = [sys.executable, '-m', 'itasc_drivers.fake_ros2_control']
D_MIN = 0.15  # config/tasks/avoid_obstacle.yaml


def run_app(app: str, mcap: Path, *, duration: float, timeout: float = 180, args: tuple[str, ...] = ()
            ) -> subprocess.CompletedProcess:
    result = subprocess.run([*BOOTSTRAP, app, '--duration', str(duration), '--record', str(mcap), *args],
                            capture_output=True, text=True, timeout=timeout)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    return result


def read(mcap: Path) -> dict[str, list]:
    """Every message by topic, decoded, in order."""
    messages: dict[str, list] = defaultdict(list)
    with AnyReader([mcap]) as reader:
        for connection, _stamp, raw in reader.messages():
            messages[connection.topic].append((connection.msgtype, reader.deserialize(raw, connection.msgtype)))
    return messages


def of_type(messages, msgtype: str) -> dict[str, list]:
    return {topic: [m for t, m in msgs if t == msgtype] for topic, msgs in messages.items()
            if msgs and msgs[0][0] == msgtype}


def check_program_outcome(messages, root: str, *, crossing: float = 1e-6) -> None:
    """``crossing``: how far AvoidObstacle's distance may go below d_min [m]."""
    states = defaultdict(list)
    for msgs in of_type(messages, 'itasc_msgs/msg/CoordinatorState').values():
        for msg in msgs:
            states[msg.composite].append(msg.state)
    assert {'itasc', 'ApproachObject', 'AvoidObstacle', 'Retreat'} <= set(states)
    for composite, sequence in states.items():
        assert any(s.startswith('Active.Run.Running') for s in sequence), composite
        assert sequence[-1].startswith('Active.Stop.Stopped'), composite
    # approach -> hold -> retreat, as the Running sub-FSM of the model says
    running = [s.removeprefix('Active.Run.Running.') for s in states['itasc'] if s.startswith('Active.Run.Running.')]
    assert running[0] == 'approach' and 'hold' in running and running[-1] == 'retreat'

    tasks = defaultdict(list)
    for msgs in of_type(messages, 'itasc_msgs/msg/TaskState').values():
        for msg in msgs:
            tasks[msg.task].append(msg)
    final = np.asarray(tasks['ApproachObject'][-1].error)
    assert np.linalg.norm(final[:3]) < 1e-3, f'final position error {np.linalg.norm(final[:3])} m'
    distances = [msg.output[0] for msg in tasks['AvoidObstacle']]
    assert len(distances) > 100 and min(distances) >= D_MIN - crossing, min(distances)

    joint_states = of_type(messages, 'sensor_msgs/msg/JointState')
    assert sum(len(m) for m in joint_states.values()) > 100
    events = [m.name for msgs in of_type(messages, 'itasc_msgs/msg/Event').values() for m in msgs]
    # the whole bring-up and stop is in the recording, from the bootstrap's first command on
    for event in (f'e_{root}_configure', 'e_itasc_deploy', 'e_ApproachObject_configure', 'e_ApproachObject_running',
                  'e_ApproachObject_arrived', f'e_{root}_stop', 'e_itasc_stopped'):
        assert event in events, event
    for sequence in states.values():
        assert sequence[0] == 'Active.Configure.Configuring.DeployEntities'


def test_approach_object_end_to_end(tmp_path):
    mcap = tmp_path / 'approach_object.mcap'
    run_app('approach_object', mcap, duration=12)
    check_program_outcome(read(mcap), 'approach_object')


def test_approach_object_with_a_process_per_composite_at_200_hz(tmp_path):
    """Each Task computes in a process of its own and its rows reach the Solver over DDS, a tick or
    more after the Solver's tick (up to 40 ms under the load of five processes). Before, the Solver
    took only rows of the last 1.5 ticks: it solved without any Task in 92-96 % of its ticks at
    500 Hz, the robot hardly moved and the program never reached retreat (at 200 Hz, with the
    Solver's remote_rows_age set to 1.5 ticks, the program still never leaves approach). A Task's
    rows now count while it is active, and drop out when it is switched off, in whichever process
    it computes. The Solver holds AvoidObstacle's bound on rows computed that long ago, so the tool
    may cross it by what it moves meanwhile (1-2 mm at 500 Hz; in one process, or at 100 Hz, it
    does not cross it). 200 Hz, not 500: on a slow two-core machine (CI's on some days) five
    processes and the recorder sustain about 350 of 500 Hz, and the rows of an overloaded Task
    process come later than remote_rows_age: this test is about late rows, the rate is a benchmark's
    (bench/bench_app.py --deploy per-composite)."""
    mcap = tmp_path / 'per_composite.mcap'
    # 15 s: the hold ends at convergence, ~10 s in (12 s left it a second or two, too little once)
    run_app('approach_object', mcap, duration=15, args=('--deploy', 'per-composite', '--rate', '200'))
    messages = read(mcap)
    # The Scene's relation reaches each Task process in the Task's trigger, not as a message of its
    # own; its topic is still there for whoever listens (here the recorder), every tick.
    relations = of_type(messages, 'itasc_msgs/msg/Features')
    assert len(relations.get('/approach_object/itasc/Scene/relation_ApproachObject', [])) > 1000
    # the bound is held on rows up to remote_rows_age (0.1 s) old, crossed by what the arm moves
    # meanwhile: 1-2 mm on a machine that keeps up, 4.3 mm seen after the runtime tests here
    check_program_outcome(messages, 'approach_object', crossing=0.01)
    solves = [tuple(m.active_tasks) for msgs in of_type(messages, 'itasc_msgs/msg/SolverStatus').values()
              for m in msgs]
    settled = solves[next((i for i, tasks in enumerate(solves) if tasks), len(solves)):]  # after the first rows came
    without = sum(not tasks for tasks in settled)
    # before: 92-96 %; now 0-4 %, up to 13 % in a loaded CI run (a Task process stalled past
    # remote_rows_age): the machine's capacity is a benchmark's, the rule that rows count is this test's
    assert without < 0.25 * len(settled), f'{without} of {len(settled)} solves without any Task'
    # retreat switches ApproachObject off and Retreat on: ApproachObject's late rows no longer count
    both = sum('ApproachObject' in tasks and 'Retreat' in tasks for tasks in solves)
    assert both <= 2, f'{both} solves with both ApproachObject and Retreat'
    # The rows the Solver combines are of one configuration (the Scene tick they were computed from).
    # Before, each Task's newest (or rows of one trigger tick, computed from relations of two Scene
    # ticks): rows of two configurations, and where AvoidObstacle's bound held the tool, a joint now and
    # then commanded at its velocity limit (2.175 rad/s) for one tick and back (3-21 such ticks a run,
    # seen in 1 of 5 CI runs; in 11 of 16 runs with a second such run alongside); the arm moves at
    # 0.1-0.3 rad/s here, as in one process.
    commands = [np.abs(m.velocity).max() for msgs in of_type(messages, 'sensor_msgs/msg/JointState').values()
                for m in msgs if len(m.velocity) and not len(m.position)]
    assert len(commands) > 100 and max(commands) < 1.0, sorted(commands)[-10:]


def test_approach_object_through_a_separate_ros2_control_like_driver(tmp_path):
    with Spawned(FAKE_ROS2_CONTROL) as driver:
        mcap = tmp_path / 'ros_driver.mcap'
        run_app('approach_object_ros_driver', mcap, duration=12)
        messages = read(mcap)
        assert driver.process.poll() is None, 'the external driver died\n' + driver.output()
    # The adapter mapped the external joint_states (reversed order, an extra finger joint) by name.
    states = of_type(messages, 'sensor_msgs/msg/JointState')['/approach_object_ros_driver/Driver_panda/joint_state']
    assert list(states[-1].name) == [f'panda_joint{i}' for i in range(1, 8)]
    check_program_outcome(messages, 'approach_object_ros_driver')


def test_mobile_manipulator_reaches_beyond_the_arm_with_the_base_moving(tmp_path):
    mcap = tmp_path / 'mobile.mcap'
    run_app('mobile_manipulator', mcap, duration=10)
    messages = read(mcap)
    reach = [m for msgs in of_type(messages, 'itasc_msgs/msg/TaskState').values() for m in msgs if m.task == 'Reach']
    assert np.linalg.norm(np.asarray(reach[-1].error)[:3]) < 1e-3
    driver = next(msgs for topic, msgs in of_type(messages, 'sensor_msgs/msg/JointState').items() if 'Driver' in topic)
    first, last = dict(zip(driver[0].name, driver[0].position)), dict(zip(driver[-1].name, driver[-1].position))
    base_travel = np.hypot(last['mobile_base_x'] - first['mobile_base_x'],
                           last['mobile_base_y'] - first['mobile_base_y'])
    assert base_travel > 0.5, f'the base moved only {base_travel:.3f} m'

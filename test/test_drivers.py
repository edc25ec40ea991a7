"""The ros2_control adapter Driver against a separate driver process that speaks only standard
messages (``fake_ros2_control``), for each of its three command interfaces: joints are matched by
name although the driver reports them in its own order with an extra joint, the program's
commands move exactly the commanded joints, and in Safety the robot stands still (README, "ROS 2
driver adapter")."""
import sys
import time

import numpy as np
import pytest
from processes import Spawned

import rclpy
from rclpy.executors import SingleThreadedExecutor

JOINTS = ['arm_a', 'arm_b', 'arm_c']          # the controller's order
INITIAL = [0.1, 0.2, 0.3]
#: The Solver's command: the program's joints in its own order, with another robot's joint.
COMMAND = {'arm_c': -0.1, 'base_x': 5.0, 'arm_a': 0.2, 'arm_b': 0.0}
RATE = 100.0


@pytest.fixture
def ros():
    rclpy.init()
    yield
    rclpy.try_shutdown()


def _run(executor, adapter, seconds: float, *, command=None, t0: float = 0.0) -> float:
    """Tick the adapter at RATE for ``seconds`` (as the Scheduler does); returns the time reached."""
    from sensor_msgs.msg import JointState

    start = time.monotonic()
    t = t0
    while time.monotonic() - start < seconds:
        if command is not None:
            adapter.inputs['command'].deliver(
                JointState(name=list(command), velocity=list(command.values())), '/test/program/command')
        t = t0 + time.monotonic() - start   # the Timer's time: the clock's
        adapter.update(t)
        executor.spin_once(timeout_sec=1.0 / RATE)
    return t


def _measured(adapter) -> np.ndarray:
    state = adapter.outputs['joint_state'].last
    assert state is not None and list(state.name) == JOINTS
    return np.array(state.position)


@pytest.mark.parametrize('interface, state_qos', [
    ('velocity', 'reliable'), ('position', 'reliable'), ('trajectory', 'reliable'),
    # joint states best effort (qos_profile_sensor_data, as many drivers and simulators publish): a
    # reliable reader never matched them, and the robot was silent for the program
    ('velocity', 'sensor_data')])
def test_the_adapter_drives_a_separate_ros2_control_driver(ros, interface, state_qos):
    from itasc_core.entity import CompositeContext
    from itasc_drivers.ros2_control_adapter import Ros2ControlAdapter

    topic = 'joint_trajectory' if interface == 'trajectory' else 'commands'
    driver = [sys.executable, '-m', 'itasc_drivers.fake_ros2_control', '--interface', interface,
              '--controller', 'arm_controller', '--joints', ','.join(JOINTS),
              '--initial', ','.join(map(str, INITIAL)), '--joint-states', '/robot/joint_states', '--rate', '200',
              '--state-qos', state_qos]
    adapter = Ros2ControlAdapter('Driver_arm', composite=CompositeContext(name='test', namespace='/test'), parameters={
        'robot': 'arm', 'joints': JOINTS, 'joint_states_topic': '/robot/joint_states',
        'command_topic': f'/arm_controller/{topic}', 'interface': interface, 'horizon': 2.0 / RATE})
    executor = SingleThreadedExecutor()
    executor.add_node(adapter)
    try:
        with Spawned(driver) as process:
            t = 0.0
            deadline = time.monotonic() + 30.0
            while adapter.outputs['joint_state'].last is None or adapter._publisher.get_subscription_count() == 0:
                assert time.monotonic() < deadline, 'no joint state from the driver\n' + process.output()
                t = _run(executor, adapter, 0.05, t0=t)
            # joints by name: the driver reports them reversed, with a gripper finger
            assert _measured(adapter) == pytest.approx(INITIAL, abs=1e-9)

            start, started = _measured(adapter), time.monotonic()
            t = _run(executor, adapter, 1.5, command=COMMAND, t0=t)
            moved, elapsed = _measured(adapter) - start, time.monotonic() - started
            expected = np.array([COMMAND[j] for j in JOINTS]) * elapsed
            assert moved[1] == pytest.approx(0.0, abs=1e-9), moved            # not commanded: still
            # each joint got its own command (by name): the motions are in the commanded ratio, and
            # about as large as commanded (a loaded machine delays the driver's execution)
            assert moved[0] / moved[2] == pytest.approx(expected[0] / expected[2], rel=0.02), (moved, expected)
            assert moved[0] == pytest.approx(expected[0], rel=0.5), (moved, expected)

            adapter.safe()    # Safety: the Scheduler stops ticking; the adapter's last word holds
            settle = time.monotonic() + 0.3
            while time.monotonic() < settle:
                executor.spin_once(timeout_sec=0.01)
            held = adapter.measured.copy()
            later = time.monotonic() + 0.5
            while time.monotonic() < later:
                executor.spin_once(timeout_sec=0.01)
            assert adapter.measured == pytest.approx(held, abs=1e-9), 'the robot moved in Safety'
    finally:
        executor.shutdown()
        adapter.destroy_node()


def test_a_driver_that_names_the_joints_otherwise_is_reported(ros):
    """A driver whose joint states lack the adapter's joints (its own names for them) does not
    measure the robot: the adapter says which joints are missing and which the driver has, once,
    instead of only falling silent."""
    from itasc_core.communication.events import EventListener
    from itasc_core.entity import CompositeContext
    from itasc_drivers.ros2_control_adapter import Ros2ControlAdapter

    composite = CompositeContext(name='test', namespace='/named')
    driver = [sys.executable, '-m', 'itasc_drivers.fake_ros2_control', '--controller', 'arm_controller',
              '--joints', 'fr3_a,fr3_b,fr3_c', '--initial', '0,0,0', '--joint-states', '/named/joint_states',
              '--rate', '200']
    adapter = Ros2ControlAdapter('Driver_arm', composite=composite, parameters={
        'robot': 'arm', 'joints': JOINTS, 'joint_states_topic': '/named/joint_states',
        'command_topic': '/arm_controller/commands'})
    heard: list = []
    EventListener(adapter, topics=[composite.events_topic], immediate=True, on_priority=heard.append)
    executor = SingleThreadedExecutor()
    executor.add_node(adapter)
    try:
        with Spawned(driver) as process:
            deadline = time.monotonic() + 30.0
            while not heard:
                assert time.monotonic() < deadline, 'nothing said of the missing joints\n' + process.output()
                _run(executor, adapter, 0.05)
            _run(executor, adapter, 0.3)  # more joint states, said once
            assert [(e.name, e.detail) for e in heard] == [
                ('e_arm_joints_missing', 'arm_a, arm_b, arm_c not in /named/joint_states (it has: fr3_c, fr3_b, fr3_a, '
                                         'panda_finger_joint1)')], heard
            assert adapter.measured is None and adapter.outputs['joint_state'].last is None
    finally:
        executor.shutdown()
        adapter.destroy_node()

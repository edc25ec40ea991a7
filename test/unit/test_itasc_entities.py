"""The Functional Entities of the constraint-based program, its Tasks and its Drivers (paper §4.1,
§4.2), as rclpy nodes in this process: connected port to port as a Composer would connect them,
updated as a Scheduler would, events observed on their composite's event topic. Real rclpy, no mocks.
"""

from __future__ import annotations

import math
import re
import time
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import rclpy
from geometry_msgs.msg import PoseStamped
from itasc_msgs.msg import ConstraintRows, Features
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message
from rclpy.time import Time
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from itasc_core.communication.events import EventListener
from itasc_core.communication.ports import LocalBus
from itasc_core.configuration import Configurator
from itasc_core.entity import CompositeContext
from itasc_core.finite import all_finite
from itasc_core.itasc import Robot
from itasc_core.itasc.entities import RobotEntity, SceneEntity, SolverEntity
from itasc_core.communication.cdr import serialize
from itasc_core.communication.samples import JointSample, as_message, as_sample
from itasc_core.itasc.entities.messages import ControlSample, FeaturesSample, stamp
from itasc_drivers.fake_ros2_control import PANDA, PANDA_READY, FakeRos2Control
from itasc_drivers.pose_sensor import PoseSensor
from itasc_drivers.ros2_control_adapter import Ros2ControlAdapter
from itasc_drivers.simulated_robot import SimulatedRobot
from itasc_tasks.entities import (ConstraintControllerEntity, ConstraintOutputEntity, ConstraintRowsEntity,
                                  SetpointGeneratorEntity, VKCEntity)

URDF = str(Path(__file__).resolve().parents[2] / 'config' / 'robots' / 'panda.urdf')
READY = dict(zip(PANDA, PANDA_READY))
DT = 0.01


@pytest.fixture(scope='module', autouse=True)
def ros():
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    yield
    rclpy.try_shutdown()


class World:
    """Entities of one test in their own composite namespace, and an executor to spin them."""

    count = 0

    def __init__(self) -> None:
        World.count += 1
        self.ctx = CompositeContext(name='itasc', namespace=f'/entities_test_{World.count}/itasc')
        self.executor = SingleThreadedExecutor()
        self.nodes = []
        self.observer = rclpy.create_node('observer', namespace=self.ctx.namespace)
        self.events = EventListener(self.observer, topics=[self.ctx.events_topic])
        self.add(self.observer)
        self.seen: list[str] = []

    def add(self, node):
        self.nodes.append(node)
        self.executor.add_node(node)
        return node

    def entity(self, cls, name: str, **parameters):
        return self.add(cls(name, composite=self.ctx, parameters=parameters))

    def spin_until(self, condition, timeout: float = 5.0) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.01)
            self.seen += [e.name for e in self.events.drain()]
            if condition():
                return True
        return False

    def close(self) -> None:
        for node in self.nodes:
            self.executor.remove_node(node)
            node.destroy_node()


@pytest.fixture
def world():
    w = World()
    yield w
    w.close()


def link(source, output: str, target, input_: str) -> None:
    target.inputs[input_].connect(source.outputs[output].topic)


def panda_limits() -> dict:
    robot = Robot('panda', URDF)
    return {'joint_names': robot.joint_names, 'lower': robot.lower.tolist(), 'upper': robot.upper.tolist(),
            'velocity_limit': robot.velocity_limit.tolist()}


# -- messages --------------------------------------------------------------------------------------

def test_features_travel_as_a_typed_message_and_back():
    jacobian = np.arange(9.0).reshape(3, 3)
    sample = FeaturesSample(1.25, ('x', 'y', 'rz'), ('j1', 'j2', 'j3'), np.array([1.0, 2.0, 3.0]), jacobian,
                            rotation=0)
    msg = as_message(sample)
    assert list(msg.names) == ['x', 'y', 'rz'] and list(msg.joint_names) == ['j1', 'j2', 'j3']
    assert (msg.stamp.sec, msg.stamp.nanosec, msg.rotation) == (1, 250_000_000, 0)
    back = as_sample(msg)
    assert back.names == sample.names and back.joint_names == sample.joint_names and back.rotation == 0
    assert np.array_equal(back.value, sample.value) and np.array_equal(back.jacobian, jacobian) and back.t == 1.25
    msg.jacobian = [1.0, 2.0]
    with pytest.raises(ValueError, match='3 names on 3 joints'):
        as_sample(msg)


def test_a_relation_written_with_its_pose_carries_the_poses_coordinates():
    """The Scene writes a relation's pose, not its coordinates: whoever reads them, in the process
    or from the message (the recorder, ``ros2 topic echo``), gets the pose's ``[p, log3(R)]``."""
    pose = pin.SE3(pin.exp3(np.array([0.3, -1.2, 2.0])), np.array([0.1, -0.2, 0.7]))
    coordinates = np.concatenate([pose.translation, pin.log3(pose.rotation)])
    sample = FeaturesSample(0.5, ('x', 'y', 'z', 'rx', 'ry', 'rz'), ('j1',), None, np.ones((6, 1)), rotation=3,
                            pose=pose)
    assert np.allclose(sample.value, coordinates)
    received = as_sample(deserialize_message(serialize(sample), Features))
    assert np.allclose(received.value, coordinates) and received.rotation == 3
    with pytest.raises(ValueError, match='value or the pose'):
        FeaturesSample(0.5, ('distance',), ('j1',), None, np.ones((1, 1)))


# -- Robot, Scene, Task entities, Solver, simulated Driver -------------------------------------------------

def test_robot_entity_maps_joints_by_name_and_reports_missing_ones(world):
    robot = world.entity(RobotEntity, 'Robot_panda', robot='panda', urdf=URDF)
    names = list(reversed(PANDA)) + ['panda_finger_joint1']
    measured = JointState(name=names, position=[READY[n] for n in names[:-1]] + [0.04])
    robot.inputs['measured'].deliver(as_sample(measured), 'x')
    robot.update(0.0)
    out = robot.outputs['joint_state'].last
    assert list(out.name) == PANDA and list(out.position) == PANDA_READY
    robot.outputs['joint_state'].last = None
    robot.inputs['measured'].deliver(as_sample(JointState(name=PANDA[:6], position=PANDA_READY[:6])), 'x')
    robot.update(0.01)
    assert robot.outputs['joint_state'].last is None
    assert world.spin_until(lambda: 'e_panda_joints_missing' in world.seen)


def test_every_relation_of_the_scene_is_written_also_when_two_relate_the_same_frames(world):
    """Two Tasks relating the same frames (computed once a tick) each get that relation, a third its own."""
    scene = world.entity(SceneEntity, 'Scene',
                         robots={'panda': {'urdf': URDF, 'frames': {'tcp': {'link': 'panda_hand_tcp'}}}},
                         objects={'target': {'xyz': [0.45, 0.1, 0.3]}, 'obstacle': {'xyz': [0.4, -0.1, 0.5]}},
                         relations={'Approach': {'o1': 'target', 'o2': 'panda/tcp'},
                                    'Retreat': {'o1': 'target', 'o2': 'panda/tcp'},
                                    'Avoid': {'o1': 'obstacle', 'o2': 'panda/tcp'}})
    scene.inputs['joint_state_panda'].deliver(JointSample(0.0, tuple(PANDA), np.array(PANDA_READY)), 'x')
    scene.update(0.5)
    for task, o1 in (('Approach', 'target'), ('Retreat', 'target'), ('Avoid', 'obstacle')):
        sample = scene.outputs[f'relation_{task}'].last
        pose = scene.scene.relative_pose(o1, 'panda/tcp')
        assert sample.t == 0.5 and np.allclose(sample.value[:3], pose.translation), task
        assert np.allclose(sample.jacobian, scene.scene.relative_jacobian(o1, 'panda/tcp')), task


def _program(world, *, setpoint: dict, weights=(1.0,)):
    """Driver -> Robot -> Scene -> Task (VKC, CO, SPG, CC, Rows) -> Solver -> Driver."""
    task = 'Approach'
    driver = world.entity(SimulatedRobot, 'Driver_panda', robot='panda', urdf=URDF,
                          initial=dict(zip(PANDA, PANDA_READY)))
    robot = world.entity(RobotEntity, 'Robot_panda', robot='panda', urdf=URDF)
    scene = world.entity(SceneEntity, 'Scene',
                         robots={'panda': {'urdf': URDF, 'frames': {'tcp': {'link': 'panda_hand_tcp'}}}},
                         objects={'target': {'xyz': [0.45, 0.1, 0.3], 'frames': {'grasp': {'rpy': [math.pi, 0, 0]}}}},
                         relations={task: {'o1': 'target/grasp', 'o2': 'panda/tcp'}})
    vkc = world.entity(VKCEntity, 'VKC', task=task, type='cartesian', o1='target/grasp', o2='panda/tcp')
    co = world.entity(ConstraintOutputEntity, 'CO', task=task)
    spg = world.entity(SetpointGeneratorEntity, 'SPG', task=task, tick_period=DT, **setpoint)
    cc = world.entity(ConstraintControllerEntity, 'CC', task=task, tick_period=DT, kp=3.0, max_output=0.5)
    rows = world.entity(ConstraintRowsEntity, 'Rows', task=task, weights=list(weights))
    solver = world.entity(SolverEntity, 'Solver', kind='qp', period=DT, **panda_limits())
    for wire in [(driver, 'joint_state', robot, 'measured'), (robot, 'joint_state', scene, 'joint_state_panda'),
                 (scene, f'relation_{task}', vkc, 'relation'), (vkc, 'features', co, 'features'),
                 (vkc, 'features', spg, 'features'), (co, 'output', cc, 'output'), (spg, 'setpoint', cc, 'setpoint'),
                 (co, 'output', rows, 'output'), (cc, 'control', rows, 'control'), (rows, 'rows', solver, 'rows'),
                 (scene, 'joint_state', solver, 'joint_state'), (solver, 'command', driver, 'command')]:
        link(*wire)
    return [driver, robot, scene, vkc, co, spg, cc, rows, solver]


def run(entities, ticks: int, start: float = 0.0) -> float:
    t = start
    for k in range(ticks):
        t = start + k * DT
        for entity in entities:
            entity.update(t)
    return t


def test_a_task_drives_the_simulated_robot_onto_the_grasp_frame(world):
    entities = _program(world, setpoint={'kind': 'minimum_jerk', 'pose': {}, 'duration': 1.5})
    driver, rows, solver, spg = entities[0], entities[7], entities[8], entities[5]
    run(entities, 150)
    assert 0.9 < spg.outputs['progress'].last.data <= 1.0
    run(entities, 250, start=1.5)
    state = rows.outputs['state'].last
    assert state.task == 'Approach' and len(state.output) == 6
    assert state.error_norm < 1e-4 and np.linalg.norm(state.output[:3]) < 1e-3
    command = solver.outputs['command'].last
    assert list(command.name) == PANDA and all(math.isfinite(v) for v in command.velocity)
    assert list(solver.outputs['status'].last.active_tasks) == ['Approach']
    assert list(driver.outputs['joint_state'].last.name) == PANDA


@pytest.mark.parametrize('task', [
    {'chain': {'type': 'cartesian'}, 'setpoint': {'kind': 'minimum_jerk', 'pose': {'xyz': [0.1, 0, 0]},
                                                  'duration': 0.05}},
    {'chain': {'type': 'cartesian', 'coordinates': 'log6'}, 'outputs': ['x', 'y', 'z'],
     'setpoint': {'kind': 'fixed', 'pose': {'rpy': [0.1, 0, 0]}}},
    {'chain': {'type': 'cartesian'}, 'outputs': ['z', 'rx', 'ry', 'rz'], 'setpoint': {'kind': 'hold'}},
    {'chain': {'type': 'distance'}, 'bounds': {'lower': [0.3]}},
    {'chain': {'type': 'point_plane', 'normal': (0.0, 1.0, 1.0)}, 'bounds': {'lower': [-0.2], 'upper': [0.1]}},
    {'chain': {'type': 'joint', 'joints': ['panda_joint2', 'panda_joint4']},
     'setpoint': {'kind': 'periodic', 'amplitude': [0.1, 0.2], 'period': 0.04}}],
    ids=['cartesian', 'log6', 'rotation', 'distance', 'point_plane', 'joint'])
def test_the_task_entities_and_task_computation_compute_the_same_rows(world, task):
    """The same Task as entities (VKC, CO, SPG, CC, Rows, fed by the Scene entity) and as one
    TaskComputation on the Scene entity's Scene: the same rows, tick by tick, the robot moving."""
    from itasc_core.itasc.robot import se3
    from itasc_tasks.controllers import PIDController
    from itasc_tasks.constraint_output import ConstraintOutput
    from itasc_tasks.setpoint_generator import FixedSetpoint, MinimumJerkSetpoint, PeriodicSetpoint
    from itasc_tasks.task import TaskComputation
    from itasc_tasks.task_types import TASK_TYPES
    o1, o2 = 'target/grasp', 'panda/tcp'
    chain, outputs, bounds = task['chain'], task.get('outputs', []), task.get('bounds')
    joints = chain['type'] == 'joint'
    scene = world.entity(SceneEntity, 'Scene',
                         robots={'panda': {'urdf': URDF, 'frames': {'tcp': {'link': 'panda_hand_tcp'}}}},
                         objects={'target': {'xyz': [0.5, 0.1, 0.3], 'rpy': [3.0, 0.2, 0.1],
                                             'frames': {'grasp': {'xyz': [0, 0, 0.05]}}}},
                         relations={'T': {'o1': o1, 'o2': o2}})
    frames = {} if joints else {'o1': o1, 'o2': o2}
    gains = {'kp': 3.0, 'ki': 2.0, 'kd': 0.01, 'max_output': 0.5}
    vkc = world.entity(VKCEntity, 'VKC', task='T', **frames, **chain)
    co = world.entity(ConstraintOutputEntity, 'CO', task='T', outputs=outputs)
    cc = world.entity(ConstraintControllerEntity, 'CC', task='T', tick_period=DT, inequality=bounds is not None,
                      **gains, **(bounds or {}))
    rows = world.entity(ConstraintRowsEntity, 'Rows', task='T', inequality=bounds is not None)
    entities = [scene, vkc, co, cc, rows]
    link(scene, 'joint_state' if joints else 'relation_T', vkc, 'joint_state' if joints else 'relation')
    for wire in [(vkc, 'features', co, 'features'), (co, 'output', cc, 'output'), (co, 'output', rows, 'output'),
                 (cc, 'control', rows, 'control')]:
        link(*wire)
    setpoint = None
    if bounds is None:
        sp = task['setpoint']
        spg = world.entity(SetpointGeneratorEntity, 'SPG', task='T', tick_period=DT, outputs=outputs, **sp)
        link(vkc, 'features', spg, 'features')
        link(spg, 'setpoint', cc, 'setpoint')
        entities.insert(3, spg)
        pose = se3(sp['pose'].get('xyz', (0, 0, 0)), sp['pose'].get('rpy', (0, 0, 0))) if 'pose' in sp else None
        setpoint = {'hold': lambda: None, 'fixed': lambda: FixedSetpoint(pose),
                    'minimum_jerk': lambda: MinimumJerkSetpoint(pose, duration=sp['duration']),
                    'periodic': lambda: PeriodicSetpoint(amplitude=sp['amplitude'], period=sp['period'])}[sp['kind']]()
    kind = TASK_TYPES[chain['type']]
    params = kind.Parameters(**frames, **{k: v for k, v in chain.items() if k != 'type'})
    computation = TaskComputation('T', vkc=kind.chain(params), **frames,
                                  output=ConstraintOutput(outputs or None), controller=PIDController(**gains),
                                  setpoint=setpoint, lower=(bounds or {}).get('lower'),
                                  upper=(bounds or {}).get('upper'))
    rng = np.random.default_rng(4)
    for k in range(8):
        t = k * DT
        q = np.array(PANDA_READY) + rng.uniform(-0.3, 0.3, 7)
        scene.inputs['joint_state_panda'].deliver(as_sample(JointState(name=PANDA, position=q.tolist())), 'robot')
        for entity in entities:
            entity.update(t)
        expected = computation.compute(scene.scene, t, DT if k else 0.0)
        got = rows.outputs['rows'].last
        assert got.t == t and got.inequality == (bounds is not None)
        for field in ('jacobian', 'desired', 'lower', 'upper'):
            want = expected.J if field == 'jacobian' else getattr(expected, field)
            np.testing.assert_allclose(getattr(got, field), want, atol=1e-12, err_msg=f'{field} at tick {k}')
        state = rows.outputs['state'].last
        np.testing.assert_allclose(state.output, computation.y, atol=1e-12)
        np.testing.assert_allclose(state.setpoint, computation.y_desired, atol=1e-12)
        assert state.error_norm == pytest.approx(computation.error_norm, abs=1e-12)


def test_setpoint_restarts_from_the_current_output_when_its_task_is_activated_again(world):
    entities = _program(world, setpoint={'kind': 'minimum_jerk', 'pose': {}, 'duration': 2.0})
    spg = entities[5]
    run(entities, 50)
    assert spg.outputs['progress'].last.data == pytest.approx(49 * DT / 2.0)
    run(entities, 2, start=10.0)  # skipped ticks alone restart nothing: the motion's time ran on
    assert spg.outputs['progress'].last.data == pytest.approx(1.0)
    spg.activate()  # the Scheduler calls this on e_<Task>_activate
    run(entities, 2, start=20.0)
    assert spg.outputs['progress'].last.data == pytest.approx(DT / 2.0)


def test_controller_gains_switch_by_parameters_as_a_configuration_does(world):
    cc = world.entity(ConstraintControllerEntity, 'CC', task='T', kp=1.0, ki=0.5)
    from rclpy.parameter import Parameter
    results = cc.set_parameters([Parameter('kp', value=8.0), Parameter('ki', value=0.0)])
    assert all(r.successful for r in results)
    assert (cc.controller.kp, cc.controller.ki) == (8.0, 0.0)
    assert not cc.set_parameters([Parameter('kp', value=-1.0)])[0].successful
    assert cc.controller.kp == 8.0


def test_inequality_controller_bounds_the_output_velocity(world):
    cc = world.entity(ConstraintControllerEntity, 'CC', task='T', kind='p', kp=5.0, inequality=True, lower=[0.15])
    assert 'setpoint' not in cc.inputs
    cc.inputs['output'].deliver(FeaturesSample(0.0, ('distance',), ('j1',), np.array([0.1]), np.array([[1.0]])), 'x')
    cc.update(0.0)
    control = cc.outputs['control'].last
    assert control.lower[0] == pytest.approx(5.0 * (0.15 - 0.1)) and control.upper[0] == math.inf


def _rows(task: str, t: float, desired: float, *, joints=PANDA) -> ConstraintRows:
    msg = ConstraintRows(task=task, rows=1, joint_names=list(joints), jacobian=[1.0] + [0.0] * (len(joints) - 1),
                         desired=[desired], lower=[desired], upper=[desired], weights=[1.0])
    msg.stamp = stamp(t)
    return msg


def _solver(world, kind: str = 'wdls'):
    solver = world.entity(SolverEntity, 'Solver', kind=kind, period=DT, **panda_limits())
    solver.inputs['joint_state'].deliver(as_sample(JointState(name=PANDA, position=PANDA_READY)), 'scene')
    return solver


def test_solver_commands_zero_and_raises_emergency_on_nan_rows(world):
    solver = _solver(world)
    solver.inputs['rows'].deliver(as_sample(_rows('Bad', 0.0, math.nan)), 'bad')
    solver.update(0.0)
    assert list(solver.outputs['command'].last.velocity) == [0.0] * 7
    assert world.spin_until(lambda: 'e_emergency' in world.seen)


def test_solver_uses_only_rows_of_this_tick_in_any_joint_order(world):
    solver = _solver(world, kind='qp')
    solver.inputs['rows'].deliver(as_sample(_rows('Old', 0.0, 0.3)), 'old')
    solver.inputs['rows'].deliver(as_sample(_rows('New', 1.0, 0.2, joints=list(reversed(PANDA)))), 'new')
    solver.update(0.99)
    solver.update(1.0)
    assert list(solver.outputs['status'].last.active_tasks) == ['New']
    assert solver.outputs['command'].last.velocity[6] == pytest.approx(0.2, abs=1e-4)  # panda_joint7


def test_solver_counts_rows_from_another_process_that_come_late_until_they_are_too_old(world):
    """A Task in another process (``--deploy per-composite``): its rows cross DDS and come a tick
    or more after the tick that triggered them. Before, only rows of the last 1.5 ticks counted, so
    the Solver solved without such a Task most of the time at 500 Hz."""
    near = world.entity(ConstraintRowsEntity, 'Near', task='Near').outputs['rows'].topic  # in this process
    solver = _solver(world, kind='qp')
    rows = solver.inputs['rows']
    rows.connect('/elsewhere/Far/Rows/rows')  # no output of that topic in this process: read over DDS
    rows.connect(near)
    assert rows.remote == {'/elsewhere/Far/Rows/rows'}
    rows.deliver(as_sample(_rows('Far', 1.0, 0.2)), '/elsewhere/Far/Rows/rows')
    rows.deliver(as_sample(_rows('Near', 1.0, 0.1, joints=list(reversed(PANDA)))), near)
    for k in range(6):  # 5 ticks later: Far's rows still count, Near's (this process) are of another tick
        solver.update(1.0 + k * DT)
    assert list(solver.outputs['status'].last.active_tasks) == ['Far']
    bus = LocalBus.of(solver.context)
    bus.set_idle('/elsewhere/Far', True)  # this process switched Far's composite off: its rows hold no more
    solver.update(1.0 + 6 * DT)
    assert list(solver.outputs['status'].last.active_tasks) == []
    bus.set_idle('/elsewhere/Far', False)
    for k in range(7, 12):  # older than remote_rows_age (0.1 s): a Task that stopped computing
        solver.update(1.0 + k * DT)
    assert list(solver.outputs['status'].last.active_tasks) == []


def _joint_rows(task: str, t: float, joint: int, desired: float) -> ConstraintRows:
    msg = _rows(task, t, desired)
    msg.jacobian = [1.0 if j == joint else 0.0 for j in range(len(PANDA))]
    return msg


def _two_tasks_elsewhere(world):
    """A QP Solver with Tasks A and B in other processes, A's rows moving joint 1 at 0.1, B's joint
    2 at 0.2, both of the configuration of 1.0, solved at 1.01; the Solver, its rows input and A's
    and B's topics."""
    solver = _solver(world, kind='qp')
    port = solver.inputs['rows']
    a, b = '/elsewhere/A/Rows/rows', '/elsewhere/B/Rows/rows'
    port.connect(a)
    port.connect(b)
    port.deliver(as_sample(_joint_rows('A', 1.0, 0, 0.1)), a)
    port.deliver(as_sample(_joint_rows('B', 1.0, 1, 0.2)), b)
    solver.update(1.01)
    assert solver.outputs['command'].last.velocity[:2] == pytest.approx([0.1, 0.2], abs=1e-4)
    return solver, port, a, b


def test_the_solver_never_combines_rows_of_two_configurations_from_other_processes(world, capfd):
    """Tasks in other processes: each one's rows come over DDS, each at its own lag. Rows describe
    the configuration they were computed at (their stamp): the Solver combines the rows of the newest
    configuration every contributing Task has rows of. Before, with no such configuration within
    ``remote_rows_age``, it took the newest of each: rows of two configurations, in which one Task's
    row is no longer quite in the row space of another's, and a joint was commanded at its velocity
    limit for a tick (test_applications.py, per composite). Now it solves again with the rows it
    last combined while they count, then holds still."""
    solver, port, a, b = _two_tasks_elsewhere(world)
    port.deliver(as_sample(_joint_rows('A', 1.02, 0, 0.3)), a)  # A's process is a tick ahead of B's
    solver.update(1.03)
    assert solver.outputs['command'].last.velocity[:2] == pytest.approx([0.1, 0.2], abs=1e-4)
    port.deliver(as_sample(_joint_rows('B', 1.02, 1, 0.4)), b)
    solver.update(1.04)
    assert solver.outputs['command'].last.velocity[:2] == pytest.approx([0.3, 0.4], abs=1e-4)
    # B's rows of 1.02 age out of remote_rows_age (0.1 s) while A and B now share no configuration
    port.deliver(as_sample(_joint_rows('A', 1.1, 0, 0.5)), a)
    port.deliver(as_sample(_joint_rows('B', 1.11, 1, 0.6)), b)
    solver.update(1.115)  # the rows last combined (1.02) still count: solved with them again
    assert solver.outputs['command'].last.velocity[:2] == pytest.approx([0.3, 0.4], abs=1e-4)
    solver.update(1.125)  # they no longer count: no rows of one configuration, it holds still
    assert solver.outputs['command'].last.velocity[:2] == pytest.approx([0.0, 0.0], abs=1e-6)
    assert list(solver.outputs['status'].last.active_tasks) == []
    assert 'the rows of A, B share no configuration within remote_rows_age (0.1 s)' in capfd.readouterr().err
    port.deliver(as_sample(_joint_rows('A', 1.11, 0, 0.7)), a)
    solver.update(1.13)
    assert solver.outputs['command'].last.velocity[:2] == pytest.approx([0.7, 0.6], abs=1e-4)


def test_the_solver_combines_rows_of_one_configuration_that_came_between_two_of_its_ticks(world):
    """Tasks in other processes: between two ticks of the Solver (its process busy) A's rows of two
    configurations came (1.02, 1.03), B's of the older only. The Solver combines the newest
    configuration both have rows of, 1.02. It kept only the newest rows of each Task at its ticks
    (A's of 1.03, B's of 1.02: none in common) and solved with older rows again, or held the robot
    still once those aged out, though rows of one configuration had come (per composite at 500 Hz:
    "share no configuration" 1-4 times in a 20 s run)."""
    solver, port, a, b = _two_tasks_elsewhere(world)
    port.deliver(as_sample(_joint_rows('A', 1.02, 0, 0.3)), a)
    port.deliver(as_sample(_joint_rows('A', 1.03, 0, 0.5)), a)
    port.deliver(as_sample(_joint_rows('B', 1.02, 1, 0.4)), b)
    solver.update(1.04)
    assert solver.outputs['command'].last.velocity[:2] == pytest.approx([0.3, 0.4], abs=1e-4)
    port.deliver(as_sample(_joint_rows('B', 1.03, 1, 0.6)), b)
    solver.update(1.05)
    assert solver.outputs['command'].last.velocity[:2] == pytest.approx([0.5, 0.6], abs=1e-4)


def test_the_solver_holds_still_while_the_rows_of_a_task_in_another_process_are_too_old(world, capfd):
    """A Task in another process whose rows stop coming (its process stalled, or died) stays in the
    problem: once its newest rows are older than ``remote_rows_age`` the Solver holds still until they
    come again. Before, the Task dropped out and the Solver moved the robot for the other Tasks
    alone: a stalled obstacle-avoidance Task's distance vanished from the problem. A Task that left
    the problem (rows of none) stays out, however long it is silent."""
    solver, port, a, b = _two_tasks_elsewhere(world)
    for k in range(2, 12):  # A computes every tick, B's process stalls: its rows of 1.0 are too old at 1.11
        port.deliver(as_sample(_joint_rows('A', 1.0 + (k - 1) * DT, 0, 0.3)), a)
        solver.update(1.0 + k * DT)
    assert solver.outputs['command'].last.velocity == pytest.approx([0.0] * 7, abs=1e-9)
    assert list(solver.outputs['status'].last.active_tasks) == []
    assert 'the rows of B are older than remote_rows_age (0.1 s): the robot holds still' in capfd.readouterr().err
    port.deliver(as_sample(_joint_rows('B', 1.1, 1, 0.4)), b)  # B's process computes again
    solver.update(1.12)
    assert solver.outputs['command'].last.velocity[:2] == pytest.approx([0.3, 0.4], abs=1e-4)
    none = ConstraintRows(task='B', rows=0, joint_names=list(PANDA))  # B's Coordinator switched it off
    none.stamp = stamp(1.12)
    port.deliver(as_sample(none), b)
    for k in range(13, 40):  # and B says nothing more: A alone
        port.deliver(as_sample(_joint_rows('A', 1.0 + (k - 1) * DT, 0, 0.5)), a)
        solver.update(1.0 + k * DT)
    assert solver.outputs['command'].last.velocity[:2] == pytest.approx([0.5, 0.0], abs=1e-4)
    assert list(solver.outputs['status'].last.active_tasks) == ['A']


def test_a_tasks_rows_are_stamped_with_the_configuration_they_describe(world):
    """A Task in another process computes its tick with the newest relation the Scene's process
    sent, which may be of an earlier tick: its features, output, rows and state carry the stamp of
    that relation (the Scene's tick, the configuration), not that of the tick that computed them, so
    that a Solver can tell rows of one configuration (before: every sample the tick's stamp)."""
    scene = world.entity(SceneEntity, 'Scene',
                         robots={'panda': {'urdf': URDF, 'frames': {'tcp': {'link': 'panda_hand_tcp'}}}},
                         objects={'target': {'xyz': [0.5, 0.1, 0.3]}},
                         relations={'T': {'o1': 'target', 'o2': 'panda/tcp'}})
    vkc = world.entity(VKCEntity, 'VKC', task='T', o1='target', o2='panda/tcp', type='cartesian')
    co = world.entity(ConstraintOutputEntity, 'CO', task='T')
    spg = world.entity(SetpointGeneratorEntity, 'SPG', task='T', tick_period=DT, kind='hold')
    cc = world.entity(ConstraintControllerEntity, 'CC', task='T', tick_period=DT, kp=1.0)
    rows = world.entity(ConstraintRowsEntity, 'Rows', task='T')
    for wire in [(scene, 'relation_T', vkc, 'relation'), (vkc, 'features', co, 'features'),
                 (vkc, 'features', spg, 'features'), (co, 'output', cc, 'output'), (spg, 'setpoint', cc, 'setpoint'),
                 (co, 'output', rows, 'output'), (cc, 'control', rows, 'control')]:
        link(*wire)
    scene.inputs['joint_state_panda'].deliver(as_sample(JointState(name=PANDA, position=PANDA_READY)), 'robot')
    scene.update(1.0)
    for t in (1.0, 1.01, 1.02):  # the Task's ticks; the Scene's newest relation is of 1.0
        for entity in (vkc, co, spg, cc, rows):
            entity.update(t)
        assert rows.outputs['rows'].last.t == 1.0 and rows.outputs['state'].last.t == 1.0
        assert vkc.outputs['features'].last.t == 1.0 and co.outputs['output'].last.t == 1.0


def test_a_task_switched_off_leaves_the_solvers_problem_at_once_wherever_it_computes(world):
    """Deactivated, the Task's Rows entity writes rows of none: the Solver drops the Task in the
    next tick, in which the rows of the tick before would still count (as those from another process
    count for ``remote_rows_age``)."""
    rows = world.entity(ConstraintRowsEntity, 'Rows', task='T')
    solver = _solver(world, kind='qp')
    solver.inputs['rows'].connect(rows.outputs['rows'].topic)
    rows.inputs['output'].deliver(FeaturesSample(1.0, ('x',), tuple(PANDA), np.array([0.3]),
                                                 np.eye(1, len(PANDA))), 'co')
    rows.inputs['control'].deliver(ControlSample(1.0, ('x',), desired=np.array([0.2]), lower=np.array([0.2]),
                                                 upper=np.array([0.2]), setpoint=np.array([0.5]),
                                                 error=np.array([0.2])), 'cc')
    rows.update(1.0)
    solver.update(1.0)
    assert list(solver.outputs['status'].last.active_tasks) == ['T']
    rows.deactivate(1.005)  # between two ticks
    solver.update(1.01)
    assert list(solver.outputs['status'].last.active_tasks) == []
    assert list(solver.outputs['command'].last.velocity) == pytest.approx([0.0] * 7, abs=1e-6)


def test_solver_raises_an_event_when_it_saturates(world):
    solver = _solver(world)
    solver.inputs['rows'].deliver(as_sample(_rows('Fast', 0.0, 100.0)), 'fast')
    solver.update(0.0)
    assert solver.outputs['status'].last.status == 'saturated'
    assert max(abs(v) for v in solver.outputs['command'].last.velocity) <= 2.175 + 1e-9
    assert world.spin_until(lambda: 'e_solver_saturated' in world.seen)


def test_simulated_robot_respects_velocity_and_position_limits(world):
    driver = world.entity(SimulatedRobot, 'Driver_panda', robot='panda', urdf=URDF,
                          initial=dict(zip(PANDA, PANDA_READY)))
    driver.inputs['command'].deliver(as_sample(JointState(name=['panda_joint4', 'other'], velocity=[50.0, 1.0])), 'x')
    for k in range(15):  # 1.4 s at 2.175 rad/s: beyond the limit
        driver.update(k * 0.1)
    state = driver.outputs['joint_state'].last
    assert state.velocity[3] == pytest.approx(2.175)
    assert state.position[3] == pytest.approx(-0.0698)  # panda_joint4's upper limit
    assert state.position[:3] == pytest.approx(PANDA_READY[:3])


def test_simulated_robot_stamps_its_joint_state_with_the_nodes_clock(world):
    """System time, unless the node uses simulated time (``use_sim_time``, rclpy's own parameter,
    which an entity leaves to rclpy): then the ROS clock's."""
    driver = world.entity(SimulatedRobot, 'Driver_panda', robot='panda', urdf=URDF)
    before = time.time()
    driver.update(0.0)
    assert before <= driver.outputs['joint_state'].last.t <= time.time()
    assert driver.set_parameters([Parameter('use_sim_time', value=True)])[0].successful
    driver.get_clock().set_ros_time_override(Time(seconds=42, nanoseconds=5_000_000))
    driver.update(0.01)
    assert driver.outputs['joint_state'].last.t == pytest.approx(42.005)
    assert driver.set_parameters([Parameter('use_sim_time', value=False)])[0].successful
    driver.update(0.02)
    assert driver.outputs['joint_state'].last.t >= before


def test_simulated_robot_moves_within_the_application_models_joint_limits(world, tmp_path):
    """The model's limits override the URDF's for the simulated robot too, not only for the Solver:
    panda_joint4 stops at the model's -1.0 (the URDF's upper limit is -0.0698) at the model's 0.5
    rad/s."""
    from itasc_bringup.apps import load_composition
    app = tmp_path / 'limits.yaml'
    config = Path(__file__).resolve().parents[2] / 'config'
    app.write_text(f'''
application:
  name: limits
  rate: 100
  program:
    robots:
      - name: panda
        urdf: {config / 'robots' / 'panda.urdf'}
        frames: [{{name: tcp, link: panda_hand_tcp}}]
        limits: {{panda_joint4: {{upper: -1.0, velocity: 0.5}}}}
    tasks:
      - {{name: Hold, type: joint, joints: [panda_joint1]}}
  drivers:
    - robot: panda
      kind: simulated
      initial: {{panda_joint4: -1.5}}
''')
    parameters = load_composition(str(app)).entity('Driver_panda').parameters
    driver = world.entity(SimulatedRobot, 'Driver_panda', **parameters)
    driver.inputs['command'].deliver(as_sample(JointState(name=['panda_joint4'], velocity=[50.0])), 'x')
    for k in range(15):  # 1.4 s at 0.5 rad/s from -1.5: beyond the model's -1.0
        driver.update(k * 0.1)
    state = driver.outputs['joint_state'].last
    assert state.velocity[3] == pytest.approx(0.5)
    assert state.position[3] == pytest.approx(-1.0)


def test_a_driver_watchdog_does_not_count_the_time_its_process_did_not_run(world):
    """A busy executor (destroying a composite's nodes, say) runs the next tick before it takes the
    joint states that arrived meanwhile: that pause is not the driver's silence. A driver that is
    really silent while the process runs is still reported within the timeout."""
    from itasc_core.computation.monitor import Monitor
    from itasc_drivers.ports import driver_ports

    spec = next(p for p in driver_ports('panda') if p.name == 'joint_state')
    monitor = world.add(Monitor('Driver_panda_silent', composite=world.ctx, watch=spec, parameters={
        'condition': 'stale', 'timeout': 0.25, 'event': 'e_emergency'}))
    state = as_sample(JointState(name=PANDA, position=PANDA_READY))
    for _ in range(5):  # a driver reporting at 100 Hz
        monitor.inputs['watch'].deliver(state, 'driver')
        monitor.update(0.0)
        time.sleep(0.01)
    time.sleep(0.4)  # the process is busy; the driver's samples wait in the queue
    monitor.update(0.0)  # the tick comes first
    monitor.inputs['watch'].deliver(state, 'driver')
    monitor.update(0.0)
    assert monitor.raised == 0
    silent_since = time.monotonic()
    while monitor.raised == 0 and time.monotonic() - silent_since < 2.0:
        monitor.update(0.0)
        time.sleep(0.01)
    assert monitor.raised == 1 and 0.25 <= time.monotonic() - silent_since < 0.4


@pytest.mark.parametrize('qos', ['reliable', 'sensor_data'])  # a localisation publishing best effort, too
def test_scene_takes_a_moving_object_pose_from_a_sensor(world, qos):
    from rclpy.qos import qos_profile_sensor_data
    sensor = world.entity(PoseSensor, 'Sensor_cup', object='cup', topic=f'{world.ctx.namespace}/cup_pose')
    scene = world.entity(SceneEntity, 'Scene', robots={'panda': {'urdf': URDF}}, objects={'cup': {'sensed': True}},
                         relations={'Look': {'o1': 'world', 'o2': 'cup'}})
    link(sensor, 'pose', scene, 'pose_cup')
    scene.inputs['joint_state_panda'].deliver(as_sample(JointState(name=PANDA, position=PANDA_READY)), 'robot')
    publisher = world.observer.create_publisher(PoseStamped, f'{world.ctx.namespace}/cup_pose',
                                                qos_profile_sensor_data if qos == 'sensor_data' else 10)
    pose = PoseStamped()
    pose.header.frame_id = 'world'
    pose.pose.position.x, pose.pose.orientation.w = 0.7, 1.0
    assert world.spin_until(lambda: publisher.get_subscription_count() > 0)
    publisher.publish(pose)
    assert world.spin_until(lambda: sensor.latest is not None)
    sensor.update(0.0)
    scene.update(0.0)
    relation = scene.outputs['relation_Look'].last
    assert relation.value[:3] == pytest.approx([0.7, 0.0, 0.0])


def test_a_topic_setpoint_published_best_effort_reaches_the_setpoint_generator(world):
    """A setpoint stream from another program (a teleoperation or a planner publishing best
    effort, ``qos_profile_sensor_data``): a reliable reader never matched it."""
    from rclpy.qos import qos_profile_sensor_data
    topic = f'{world.ctx.namespace}/target'
    spg = world.entity(SetpointGeneratorEntity, 'SPG', task='T', tick_period=DT, kind='topic', topic=topic,
                       outputs=['x'])
    publisher = world.observer.create_publisher(Float64MultiArray, topic, qos_profile_sensor_data)
    assert world.spin_until(lambda: publisher.get_subscription_count() > 0)
    publisher.publish(Float64MultiArray(data=[0.42]))
    assert world.spin_until(lambda: spg.generator.value is not None)
    assert list(spg.generator.value) == [0.42]


# -- the ROS 2 driver adapter against a driver that speaks only standard messages ----------------------------

def test_ros2_control_adapter_maps_joints_by_name_and_commands_in_controller_order(world):
    ns = world.ctx.namespace
    fake = world.add(FakeRos2Control(joints=PANDA, initial=PANDA_READY, extra_joint='panda_finger_joint1',
                                     controller=f'{ns.strip("/")}/velocity_controller', interface='velocity',
                                     rate=100.0, joint_states=f'{ns}/joint_states'))
    adapter = world.entity(Ros2ControlAdapter, 'Driver_panda', robot='panda', joints=PANDA,
                           joint_states_topic=f'{ns}/joint_states', command_topic=f'{ns}/velocity_controller/commands')
    assert world.spin_until(lambda: adapter.measured is not None)
    adapter.update(0.0)
    assert list(adapter.outputs['joint_state'].last.name) == PANDA
    assert list(adapter.outputs['joint_state'].last.position) == pytest.approx(PANDA_READY)
    velocity = [0.1 * (i + 1) for i in range(7)]
    command = JointState(name=list(reversed(PANDA)), velocity=list(reversed(velocity)))
    adapter.inputs['command'].deliver(as_sample(command), 's')
    adapter.update(0.01)
    assert world.spin_until(lambda: [fake.velocities[j] for j in PANDA] == pytest.approx(velocity))
    adapter.disengage()
    assert world.spin_until(lambda: all(v == 0.0 for v in fake.velocities.values()))


def test_ros2_control_adapter_integrates_positions_for_a_position_controller(world):
    ns = world.ctx.namespace
    received: list[Float64MultiArray] = []
    world.observer.create_subscription(Float64MultiArray, f'{ns}/position_controller/commands', received.append, 10)
    adapter = world.entity(Ros2ControlAdapter, 'Driver_panda', robot='panda', joints=PANDA, interface='position',
                           joint_states_topic=f'{ns}/joint_states', command_topic=f'{ns}/position_controller/commands')
    adapter._on_state(JointState(name=PANDA, position=PANDA_READY))
    adapter.inputs['command'].deliver(as_sample(JointState(name=PANDA, velocity=[1.0] + [0.0] * 6)), 's')
    assert world.spin_until(lambda: adapter._publisher.get_subscription_count() > 0)
    for k in range(3):
        adapter.update(k * 0.1)
    assert world.spin_until(lambda: len(received) == 3)
    assert received[-1].data[0] == pytest.approx(PANDA_READY[0] + 0.2)


@pytest.mark.parametrize('interface', ['position', 'trajectory'])
def test_ros2_control_adapter_never_commands_a_position_the_driver_measured_as_nan(world, interface):
    """A driver reporting a non-finite joint position: the adapter hands it on (the watchdog puts
    the program in Safety), and in Safety holds each joint at its last finite position. Before,
    every hold command of a position or trajectory controller carried the NaN, tick after tick;
    and none is sent before every joint had a finite position."""
    from trajectory_msgs.msg import JointTrajectory
    ns = world.ctx.namespace
    topic = f'{ns}/controller/{"commands" if interface == "position" else "joint_trajectory"}'
    received: list = []
    world.observer.create_subscription(Float64MultiArray if interface == 'position' else JointTrajectory, topic,
                                       received.append, 10)
    adapter = world.entity(Ros2ControlAdapter, 'Driver_panda', robot='panda', joints=PANDA, interface=interface,
                           joint_states_topic=f'{ns}/joint_states', command_topic=topic)
    assert world.spin_until(lambda: adapter._publisher.get_subscription_count() > 0)

    def positions(message) -> list[float]:
        return list(message.data if interface == 'position' else message.points[0].positions)
    broken = [math.nan] + PANDA_READY[1:]
    adapter._on_state(JointState(name=PANDA, position=broken))  # never a finite position of joint 1
    adapter.safe()
    adapter.update(0.0)
    world.spin_until(lambda: received, timeout=0.5)
    assert received == [] and not all_finite(adapter.outputs['joint_state'].last.position)

    adapter._on_state(JointState(name=PANDA, position=PANDA_READY))
    adapter.update(0.01)
    assert world.spin_until(lambda: len(received) == 1)
    for _ in range(3):  # the driver's joint 1 goes NaN; Safety follows, every tick holds the robot
        adapter._on_state(JointState(name=PANDA, position=broken))
        adapter.safe()
    assert world.spin_until(lambda: len(received) == 4)
    assert not all_finite(adapter.outputs['joint_state'].last.position)  # reported as measured
    assert [positions(m) for m in received[1:]] == [pytest.approx(PANDA_READY)] * 3, received


def test_an_entity_refuses_invalid_parameters_at_construction(world):
    with pytest.raises(ValueError, match='CC_bad: kp: Input should be greater than or equal to 0'):
        world.entity(ConstraintControllerEntity, 'CC_bad', task='T', kp=-1.0)


def _call(world, client, future):
    assert world.spin_until(future.done), 'no answer from the parameter services'
    return future.result()


def test_parameters_are_declared_typed_described_and_bounded_from_the_entitys_model(world):
    """What ``ros2 param describe`` shows of an entity (through its composite's Configurator, as
    ``<entity>.<parameter>``) comes from its parameter model: the type (also of an empty list), the
    field's docstring and its bounds; a change the model refuses is refused with its reason, one it
    accepts takes effect. The entity itself offers no parameter services."""
    from rcl_interfaces.msg import ParameterType
    from rclpy.parameter import Parameter
    from rclpy.parameter_client import AsyncParameterClient

    cc = world.entity(ConstraintControllerEntity, 'CC', task='T', kp=2)
    co = world.entity(ConstraintOutputEntity, 'CO', task='T')
    world.add(Configurator(composite=world.ctx, configurations={}, initial=[], entities=lambda: {'CC': cc, 'CO': co}))
    client = AsyncParameterClient(world.observer, f'{world.ctx.namespace}/configurator')
    assert client.wait_for_services(timeout_sec=5.0)
    assert not AsyncParameterClient(world.observer, f'{world.ctx.namespace}/CC').wait_for_services(timeout_sec=0.5)
    names = _call(world, client, client.list_parameters(['CC'], 1)).result.names
    assert {'CC.kp', 'CC.kind', 'CC.max_output'} <= set(names) and not any(n.startswith('CO.') for n in names)
    kp, kind, outputs = _call(world, client, client.describe_parameters(['CC.kp', 'CC.kind', 'CO.outputs'])).descriptors
    assert kp.name == 'CC.kp' and cc.describe_parameter('kp').name == 'kp'  # the entity's own stays as it was
    assert kp.type == ParameterType.PARAMETER_DOUBLE and 'Proportional gain' in kp.description
    assert (kp.floating_point_range[0].from_value, kp.floating_point_range[0].to_value) == (0.0, math.inf)
    assert kind.type == ParameterType.PARAMETER_STRING and kind.read_only  # another law: a swap, not a set
    assert outputs.type == ParameterType.PARAMETER_STRING_ARRAY  # an empty list, typed by the model
    refused = _call(world, client, client.set_parameters([Parameter('CC.max_output', value=0.0)])).results[0]
    assert not refused.successful and 'max_output: Input should be greater than 0' in refused.reason
    assert cc.controller.max_output == math.inf
    unknown = _call(world, client, client.set_parameters([Parameter('VKC.kp', value=1.0)])).results[0]
    assert not unknown.successful and "entities ['CC', 'CO']" in unknown.reason
    accepted = _call(world, client, client.set_parameters([Parameter('CC.kp', value=5.0)])).results[0]
    assert accepted.successful and cc.controller.kp == 5.0
    (value,) = _call(world, client, client.get_parameters(['CC.kp'])).values
    assert value.double_value == 5.0
    both = _call(world, client, client.set_parameters_atomically([Parameter('CC.kp', value=1.0),
                                                                   Parameter('CO.outputs', value=['x'])])).result
    assert not both.successful and 'one entity at a time' in both.reason and cc.controller.kp == 5.0


def test_a_parameter_change_is_announced_as_the_configurators_on_parameter_events(world):
    """Tools that show a node's parameters live (rqt_reconfigure, Foxglove's parameter panel) list
    them with the node's services and follow ``/parameter_events`` for that node: a change, from
    ``ros2 param set`` or a named configuration, reaches them as ``<entity>.<parameter>`` of the
    Configurator that lists it; a refused change does not."""
    from rclpy.parameter import Parameter
    from rclpy.parameter_client import AsyncParameterClient
    from rclpy.parameter_event_handler import ParameterEventHandler

    cc = world.entity(ConstraintControllerEntity, 'CC', task='T', kp=2)
    configurator = world.add(Configurator(composite=world.ctx, configurations={'fast': {'CC': {'kp': 8.0}}},
                                          initial=[], entities=lambda: {'CC': cc}))
    name = configurator.get_fully_qualified_name()
    heard: list[float] = []
    handler = ParameterEventHandler(world.observer)
    handle = handler.add_parameter_callback('CC.kp', name, lambda p: heard.append(p.value.double_value))
    client = AsyncParameterClient(world.observer, name)
    assert client.wait_for_services(timeout_sec=5.0)
    events, writers = handler.parameter_event_subscription, world.observer.count_publishers
    assert world.spin_until(lambda: events.get_publisher_count() >= writers('/parameter_events'))  # all matched
    assert _call(world, client, client.set_parameters([Parameter('CC.kp', value=5.0)])).results[0].successful
    assert world.spin_until(lambda: heard == [5.0]), heard
    assert not _call(world, client, client.set_parameters([Parameter('CC.kp', value=-1.0)])).results[0].successful
    assert configurator.apply('fast') is None
    assert world.spin_until(lambda: heard == [5.0, 8.0]), heard
    assert cc.controller.kp == 8.0
    handler.remove_parameter_callback(handle)


@pytest.mark.parametrize('answer', ['maybe', None, 1.0, [True]])
def test_a_condition_that_answers_neither_true_nor_false_is_an_error_not_a_yes(world, answer):
    """A condition plugin whose holds() returned 'maybe' made its Monitor raise its event, as if the
    condition held; such an answer is the plugin's error (the Scheduler takes it to Safety, named)."""
    from itasc_core.computation.monitor import Monitor
    from itasc_drivers.ports import driver_ports

    spec = next(p for p in driver_ports('panda') if p.name == 'joint_state')
    monitor = world.add(Monitor('far', composite=world.ctx, watch=spec, parameters={
        'field': 'position[0]', 'condition': 'above', 'threshold': 1.0, 'event': 'e_far'}))
    monitor.condition.holds = lambda values, **_: answer
    monitor.inputs['watch'].deliver(as_sample(JointState(name=PANDA, position=PANDA_READY)), 'driver')
    with pytest.raises(TypeError, match=f"condition 'above' of far answered {re.escape(repr(answer))}, not True"):
        monitor.update(0.0)
    assert monitor.raised == 0


def test_a_task_commanded_to_stop_holds_the_robot_still_and_is_no_fault_to_say(world, capfd):
    """At the end of a per-composite run the program's Coordinator stops its Tasks (``e_<task>_stop``)
    while its Scheduler still ticks the Solver: their rows stop coming. The Solver holds the robot
    still, as for any Task whose rows stop coming (it never drops, say, an avoidance constraint), but
    it also said "the rows of B are older than remote_rows_age (0.1 s): the robot holds still until
    they come" after most stops, a fault that was none. A Task's composite that this process
    commanded to stop (:meth:`LocalBus.set_stopping`) holds the robot still without a word; once
    started anew, it is said again."""
    solver, port, a, b = _two_tasks_elsewhere(world)
    bus = LocalBus.of(solver.context)
    bus.set_stopping('/elsewhere/B', True)
    for k in range(2, 12):  # A computes every tick, B stopped: its rows of 1.0 are too old at 1.11
        port.deliver(as_sample(_joint_rows('A', 1.0 + (k - 1) * DT, 0, 0.3)), a)
        solver.update(1.0 + k * DT)
    assert solver.outputs['command'].last.velocity == pytest.approx([0.0] * 7, abs=1e-9)
    assert list(solver.outputs['status'].last.active_tasks) == []
    assert 'older than remote_rows_age' not in capfd.readouterr().err
    bus.set_stopping('/elsewhere/B', False)
    port.deliver(as_sample(_joint_rows('A', 1.11, 0, 0.3)), a)
    solver.update(1.12)
    assert solver.outputs['command'].last.velocity == pytest.approx([0.0] * 7, abs=1e-9)
    assert 'the rows of B are older than remote_rows_age (0.1 s): the robot holds still' in capfd.readouterr().err

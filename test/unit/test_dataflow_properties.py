"""Property-based test of the data-flow inputs of a constraint-based program (issue #8; README
"Faults and bad input", "Data-flow inputs").

The real entities of approach_object's program run as rclpy nodes in this process, connected port
to port and ticked by a real Scheduler: Robot, a PoseSensor measuring the target from a topic,
Scene, Task ApproachObject (Cartesian VKC, CO, setpoint generator of kind ``topic``, CC, rows),
Task AvoidObstacle (distance inequality), the Solver (``wdls`` with a PID controller, ``qp`` with
a P controller), the Driver watchdog Monitor (non-finite joint positions) and a tracking Monitor.
The test plays the Driver (joint states written on a Driver's output port), the publishers of the
target pose and of the setpoint (on their ROS topics) and the Coordinator (``e_emergency`` ->
``e_itasc_safety``). hypothesis feeds them anything: NaN, +-inf, huge and tiny values, missing,
extra and duplicated joints, lists of the wrong length, zero, non-normalised and overflowing
quaternions.

Properties, for every input sequence:

* every command the Solver writes names the program's joints, is finite and within the joint
  velocity limits;
* an invalid input (a non-finite position of a robot joint, a target pose that is not finite or
  whose quaternion has no direction, a setpoint that is not finite or has the wrong number of
  values) raises ``e_emergency``;
* after ``e_emergency`` the Scheduler is in Safety and the command is zero.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pytest
import rclpy
from geometry_msgs.msg import PoseStamped
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rclpy.executors import SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from itasc_core.communication.events import EventListener, EventRaiser
from itasc_core.communication.ports import InputPort, OutputPort, PortSpec
from itasc_core.computation.monitor import Monitor
from itasc_core.coordination.scheduler import Scheduler
from itasc_core.entity import CompositeContext
from itasc_core.itasc import Robot
from itasc_core.itasc.entities import RobotEntity, SceneEntity, SolverEntity
from itasc_core.itasc.entities.robot_entity import joint_positions
from itasc_drivers.pose_sensor import PoseSensor
from itasc_tasks.entities import (ConstraintControllerEntity, ConstraintOutputEntity, ConstraintRowsEntity,
                                  SetpointGeneratorEntity, VKCEntity)

URDF = str(Path(__file__).resolve().parents[2] / 'config' / 'robots' / 'panda.urdf')
PANDA = [f'panda_joint{i}' for i in range(1, 8)]
READY = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]
TARGET = (0.55, 0.15, 0.2)
DT = 0.01
EXAMPLES = 150  # per Solver kind


@pytest.fixture(scope='module', autouse=True)
def ros():
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    yield
    rclpy.try_shutdown()


@dataclass
class Step:
    """What arrives before one tick: a joint state from the Driver, a target pose, a setpoint."""

    joints: tuple[list[str], list[float]] | None
    pose: tuple[float, ...] | None  # x, y, z, qx, qy, qz, qw
    setpoint: list[float] | None


@dataclass
class Outcome:
    commands: list[JointState]
    emergencies: list[str]
    safety: bool


class Program:
    """approach_object's program with a sensed target and a setpoint from a topic, in this process."""

    def __init__(self, kind: str, controller: str) -> None:
        self.ctx = CompositeContext(name='itasc', namespace=f'/dataflow_{kind}/itasc')
        ns = self.ctx.namespace
        self.executor = SingleThreadedExecutor()
        self.nodes: list = []
        self.observer = self._add(rclpy.create_node('observer', namespace=ns))
        self.raiser = EventRaiser(self.observer, topic=self.ctx.events_topic)
        self.emergencies: list[str] = []
        self.synced = 0
        self.listener = EventListener(self.observer, topics=[self.ctx.events_topic], on_priority=self._on_event,
                                      immediate=True)
        driver_spec = PortSpec(name='joint_state', direction='output', msg_type=JointState, type='joint_state',
                               semantics=joint_positions('panda'))
        self.driver = OutputPort(self.observer, driver_spec.with_id(f'{ns}/Driver_panda/joint_state'))
        self.pose_publisher = self.observer.create_publisher(PoseStamped, f'{ns}/target_pose', 10)
        self.setpoint_publisher = self.observer.create_publisher(Float64MultiArray, f'{ns}/setpoint', 10)
        robot = Robot('panda', URDF)
        self.velocity_limit = robot.velocity_limit.copy()

        e = self._entity
        self.robot = e(RobotEntity, 'Robot_panda', robot='panda', urdf=URDF)
        self.sensor = e(PoseSensor, 'Sensor_target', object='target', topic=f'{ns}/target_pose')
        self.scene = e(SceneEntity, 'Scene',
                       robots={'panda': {'urdf': URDF, 'frames': {'tcp': {'link': 'panda_hand_tcp'}}}},
                       objects={'target': {'xyz': list(TARGET), 'sensed': True,
                                           'frames': {'grasp': {'xyz': [0, 0, 0.05], 'rpy': [math.pi, 0, 0]}}},
                                'obstacle': {'xyz': [0.45, -0.05, 0.5]}},
                       relations={'Approach': {'o1': 'target/grasp', 'o2': 'panda/tcp'},
                                  'Avoid': {'o1': 'obstacle', 'o2': 'panda/panda_hand'}})
        approach = [e(VKCEntity, 'A_VKC', task='Approach', type='cartesian', o1='target/grasp', o2='panda/tcp'),
                    e(ConstraintOutputEntity, 'A_CO', task='Approach'),
                    e(SetpointGeneratorEntity, 'A_SPG', task='Approach', kind='topic', topic=f'{ns}/setpoint'),
                    e(ConstraintControllerEntity, 'A_CC', task='Approach', kind=controller, kp=2.0,
                      max_output=0.5, **({'ki': 1.0} if controller == 'pid' else {})),
                    e(ConstraintRowsEntity, 'A_Rows', task='Approach', priority=1,
                      weights=[1.0, 1.0, 1.0, 0.5, 0.5, 0.5])]
        self.spg = approach[2]
        avoid = [e(VKCEntity, 'O_VKC', task='Avoid', type='distance', o1='obstacle', o2='panda/panda_hand'),
                 e(ConstraintOutputEntity, 'O_CO', task='Avoid'),
                 e(ConstraintControllerEntity, 'O_CC', task='Avoid', kind='p', kp=5.0, inequality=True,
                   lower=[0.15]),
                 e(ConstraintRowsEntity, 'O_Rows', task='Avoid', priority=0, inequality=True)]
        self.solver = e(SolverEntity, 'Solver', kind=kind, period=DT, joint_names=robot.joint_names,
                        lower=robot.lower.tolist(), upper=robot.upper.tolist(),
                        velocity_limit=robot.velocity_limit.tolist())
        self.entities = [self.robot, self.sensor, self.scene, *approach, *avoid, self.solver]
        self.monitors = [
            self._add(Monitor('Driver_panda_nonfinite', composite=self.ctx, watch=driver_spec,
                              parameters={'field': 'position', 'condition': 'nonfinite', 'event': 'e_emergency'})),
            self._add(Monitor('tracking_error', composite=self.ctx, watch=approach[4].outputs['state'].spec,
                              parameters={'field': 'error_norm', 'condition': 'above', 'threshold': 0.02,
                                          'event': 'e_max_pos_tracking_error_exc'}))]
        self.monitors[0].watch.connect(self.driver.topic)
        self.monitors[1].watch.connect(approach[4].outputs['state'].topic)
        wires = [(self.driver, self.robot, 'measured'),
                 (self.robot.outputs['joint_state'], self.scene, 'joint_state_panda'),
                 (self.sensor.outputs['pose'], self.scene, 'pose_target'),
                 (self.scene.outputs['joint_state'], self.solver, 'joint_state'),
                 (approach[0].outputs['features'], self.spg, 'features'),
                 (self.spg.outputs['setpoint'], approach[3], 'setpoint')]
        for task, (vkc, co, *_, cc, rows) in (('Approach', approach), ('Avoid', avoid)):
            wires += [(self.scene.outputs[f'relation_{task}'], vkc, 'relation'),
                      (vkc.outputs['features'], co, 'features'),
                      (co.outputs['output'], cc, 'output'), (co.outputs['output'], rows, 'output'),
                      (cc.outputs['control'], rows, 'control'), (rows.outputs['rows'], self.solver, 'rows')]
        for output, entity, port in wires:
            entity.inputs[port].connect(output.topic)
        self.commands: list[JointState] = []
        command = self.solver.outputs['command'].spec
        self.command_sink = InputPort(self.observer, replace(command, direction='input'),
                                      on_sample=self.commands.append)
        self.command_sink.connect(self.solver.outputs['command'].topic)

        self.scheduler = self._add(Scheduler(composite=self.ctx))
        for entity in self.entities:
            self.scheduler.add_entity(entity)
        for monitor in self.monitors:
            self.scheduler.add_monitor(monitor)
        self.t = 0.0

    # -- building and tearing down ----------------------------------------------------------------

    def _add(self, node):
        self.nodes.append(node)
        self.executor.add_node(node)
        return node

    def _entity(self, cls, name: str, **parameters):
        return self._add(cls(name, composite=self.ctx, parameters=parameters))

    def close(self) -> None:
        self.command_sink.disconnect()
        self.driver.destroy()
        for node in reversed(self.nodes):
            self.executor.remove_node(node)
            node.destroy_node()

    # -- the Coordinator's part: e_emergency puts the Scheduler in Safety ------------------------------

    def _on_event(self, msg) -> None:
        if msg.name == 'e_emergency':
            if not self.emergencies:
                self.raiser.raise_event(f'e_{self.ctx.name}_safety')
            self.emergencies.append(msg.detail)
        elif msg.name == 'e_probe_sync':
            self.synced += 1

    def spin_until(self, condition, timeout: float = 5.0) -> bool:
        deadline = time.monotonic() + timeout
        while not condition():
            if time.monotonic() > deadline:
                return False
            self.executor.spin_once(timeout_sec=0.001)
        return True

    def sync(self) -> None:
        """Every event raised so far has arrived (one of ours raised after them came back)."""
        expected = self.synced + 1
        self.raiser.raise_event('e_probe_sync')
        assert self.spin_until(lambda: self.synced >= expected)
        for _ in range(5):
            self.executor.spin_once(timeout_sec=0.0)

    def start(self) -> None:
        """Fresh computation state, the Scheduler running (as after Configure and Start)."""
        assert self.spin_until(lambda: self.raiser.publisher.get_subscription_count() >= 4)
        for entity in self.entities:
            if entity is not self.sensor:  # its subscription stays matched with our publisher
                entity.configure(entity.params)
            entity.activate()
            for port in entity.inputs.values():
                port.latest = None
                port.samples.clear()
        self.sensor.latest = None
        for name in ('scheduler_initialize', 'scheduler_activate'):
            self.raiser.raise_event(f'e_{self.ctx.name}_{name}')
        assert self.spin_until(lambda: self.scheduler.active and not self.scheduler.safety)
        self.sync()
        self.emergencies.clear()
        self.commands.clear()

    # -- inputs -----------------------------------------------------------------------------------

    def publish_pose(self, pose: tuple[float, ...]) -> None:
        msg = PoseStamped()
        msg.header.frame_id = 'world'
        p, q = msg.pose.position, msg.pose.orientation
        p.x, p.y, p.z, q.x, q.y, q.z, q.w = pose
        before = self.sensor.latest
        self.pose_publisher.publish(msg)
        assert self.spin_until(lambda: self.sensor.latest is not before)

    def publish_setpoint(self, values: list[float]) -> None:
        before = self.spg.generator.value
        self.setpoint_publisher.publish(Float64MultiArray(data=values))
        assert self.spin_until(lambda: self.spg.generator.value is not before)

    def tick(self) -> None:
        self.scheduler.tick(self.t)
        self.t += DT
        for _ in range(3):
            self.executor.spin_once(timeout_sec=0.0)

    def run(self, steps: list[Step]) -> Outcome:
        self.start()
        self.publish_pose((*TARGET, 0.0, 0.0, 0.0, 1.0))
        for _ in range(2):
            self.driver.write(JointState(name=PANDA, position=READY))
            self.tick()
        for step in steps:
            if step.pose is not None:
                self.publish_pose(step.pose)
            if step.setpoint is not None:
                self.publish_setpoint(step.setpoint)
            if step.joints is not None:
                self.driver.write(JointState(name=step.joints[0], position=step.joints[1]))
            self.tick()
        self.sync()
        if self.emergencies:
            assert self.spin_until(lambda: self.scheduler.safety), 'e_emergency did not lead to Safety'
            self.tick()  # a tick in Safety
        outcome = Outcome(list(self.commands), list(self.emergencies), self.scheduler.safety)
        self.t += 1.0
        return outcome


# -- what a user would call invalid ---------------------------------------------------------------------

def invalid(step: Step) -> list[str]:
    why = []
    if step.joints is not None:
        by_name = dict(zip(*step.joints))
        if all(n in by_name for n in PANDA) and not all(math.isfinite(by_name[n]) for n in PANDA):
            why.append('non-finite joint position')
    if step.pose is not None:
        quaternion = step.pose[3:]
        if not all(math.isfinite(v) for v in step.pose) or not any(quaternion):
            why.append('target pose not finite or without orientation')
    if step.setpoint is not None and (len(step.setpoint) != 6 or not all(math.isfinite(v) for v in step.setpoint)):
        why.append('setpoint not finite or of the wrong size')
    return why


# -- strategies ------------------------------------------------------------------------------------------

SPECIAL = [math.nan, math.inf, -math.inf, 1e300, -1e300, 1.7976931348623157e308, 5e-324, -0.0, 1e-200]
number = st.one_of(st.floats(-3.0, 3.0), st.sampled_from(SPECIAL), st.floats())
small = st.floats(-0.2, 0.2)


@st.composite
def joint_states(draw, *, valid: bool) -> tuple[list[str], list[float]]:
    shape = draw(st.sampled_from(['ready'] if valid else ['ready', 'one_bad', 'any']))
    if shape == 'any':  # missing, extra, duplicated joints; positions of any length
        names = draw(st.lists(st.sampled_from(PANDA + ['panda_finger_joint1', 'base_x', '']), max_size=10))
        return names, draw(st.lists(number, max_size=10))
    names = draw(st.permutations(PANDA + draw(st.sampled_from([[], ['panda_finger_joint1']]))))
    positions = [READY[PANDA.index(n)] + draw(small) if n in PANDA else 0.04 for n in names]
    if shape == 'one_bad':
        positions[draw(st.integers(0, len(names) - 1))] = draw(number)
    return names, positions


@st.composite
def poses(draw, *, valid: bool) -> tuple[float, ...]:
    near = st.tuples(*(st.floats(v - 0.1, v + 0.1) for v in TARGET))
    position = draw(near if valid else st.one_of(near, st.tuples(number, number, number)))
    shape = draw(st.sampled_from(['unit', 'scaled'] if valid else ['unit', 'scaled', 'zero', 'any']))
    if shape == 'zero':
        return (*position, 0.0, 0.0, 0.0, 0.0)
    if shape == 'any':
        return (*position, *draw(st.tuples(number, number, number, number)))
    q = np.array(draw(st.tuples(small, small, small, st.floats(0.5, 1.0))))
    q /= np.linalg.norm(q)
    scale = 1.0 if shape == 'unit' else draw(st.sampled_from([1e-200, 1e-3, 2.0, 1e200, 1e308]))
    return (*position, *(float(v) * scale for v in q))


@st.composite
def steps(draw) -> list[Step]:
    """Input sequences: valid throughout (the program runs and moves), valid but for one field of
    one step, or anything at all."""
    mode = draw(st.sampled_from(['valid', 'one_fault', 'any']))
    good_setpoint = st.lists(st.floats(-0.1, 0.1), min_size=6, max_size=6)
    any_setpoint = st.one_of(good_setpoint, st.lists(number, max_size=8))

    def step(valid: bool):
        return st.builds(Step, joints=st.one_of(st.none(), joint_states(valid=valid)),
                         pose=st.one_of(st.none(), poses(valid=valid)),
                         setpoint=st.one_of(st.none(), good_setpoint if valid else any_setpoint))
    sequence = draw(st.lists(step(mode != 'any'), min_size=1, max_size=6))
    if mode == 'one_fault':
        i, field = draw(st.integers(0, len(sequence) - 1)), draw(st.sampled_from(['joints', 'pose', 'setpoint']))
        fault = {'joints': joint_states(valid=False), 'pose': poses(valid=False), 'setpoint': any_setpoint}[field]
        sequence[i] = replace(sequence[i], **{field: draw(fault)})
    return sequence


# -- the property ------------------------------------------------------------------------------------------

@pytest.mark.filterwarnings('ignore::RuntimeWarning')  # numpy on inf - inf: what the property is about
@pytest.mark.parametrize('kind, controller', [('wdls', 'pid'), ('qp', 'p')])
def test_no_input_makes_the_solver_command_a_non_finite_or_too_fast_velocity(kind, controller):
    program = Program(kind, controller)
    seen = {'examples': 0, 'moved': 0, 'safety': 0}
    limit = program.velocity_limit

    @settings(max_examples=EXAMPLES, derandomize=True, deadline=None, database=None,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
    @given(steps=steps())
    def check(steps: list[Step]) -> None:
        outcome = program.run(steps)
        seen['examples'] += 1
        for command in outcome.commands:
            velocity = np.asarray(command.velocity)
            assert list(command.name) == PANDA and velocity.shape == (7,)
            assert np.isfinite(velocity).all(), f'non-finite command {velocity}'
            assert (np.abs(velocity) <= limit).all(), f'command {velocity} beyond the limits {limit}'
        reasons = [why for step in steps for why in invalid(step)]
        if reasons:
            assert outcome.emergencies, f'no e_emergency for: {reasons}'
        if outcome.emergencies:
            assert outcome.safety and not any(outcome.commands[-1].velocity), \
                f'not commanding zero in Safety after {outcome.emergencies}'
            seen['safety'] += 1
        elif any(np.abs(c.velocity).max() > 1e-3 for c in outcome.commands):
            seen['moved'] += 1

    try:
        check()
    finally:
        program.close()
    # every example ran, and the inputs reached both outcomes: a program that moves, and Safety
    assert seen['examples'] >= EXAMPLES and seen['moved'] >= 20 and seen['safety'] >= 20, seen


# -- regressions: what the property found ---------------------------------------------------------------------

def _run_each(program: Program, cases: dict[str, list[Step]]) -> dict[str, Outcome]:
    try:
        return {name: program.run(case) for name, case in cases.items()}
    finally:
        program.close()


def test_a_broken_target_pose_puts_the_program_in_safety_and_any_other_quaternion_is_normalised():
    """Found by the property: a zero quaternion (and one whose norm overflowed) was taken for the
    identity, a target at infinity was approached at full speed, both without e_emergency."""
    unit = (0.0, 0.0, 0.6, 0.8)
    outcomes = _run_each(Program('qp', 'p'), {
        'zero quaternion': [Step(None, (*TARGET, 0.0, 0.0, 0.0, 0.0), None)],
        'target at infinity': [Step(None, (0.0, 0.0, math.inf, *unit), None)],
        'nan quaternion': [Step(None, (*TARGET, math.nan, 0.0, 0.0, 1.0), None)],
        'unit': [Step(None, (*TARGET, *unit), None)] * 3,
        'huge': [Step(None, (*TARGET, *(1e308 * v for v in unit)), None)] * 3,
        'tiny': [Step(None, (*TARGET, *(1e-300 * v for v in unit)), None)] * 3})
    for name in ('zero quaternion', 'target at infinity', 'nan quaternion'):
        outcome = outcomes[name]
        assert 'target: measured pose not finite or its quaternion zero' in outcome.emergencies, name
        assert outcome.safety and not any(outcome.commands[-1].velocity), name
    moving = outcomes['unit'].commands[-1].velocity
    assert np.abs(moving).max() > 0.01
    for name in ('huge', 'tiny'):
        assert not outcomes[name].emergencies
        assert outcomes[name].commands[-1].velocity == pytest.approx(moving, abs=1e-9), name


def test_a_setpoint_from_a_topic_that_is_not_finite_or_not_one_per_output_puts_the_program_in_safety():
    """Found by the property: with a P controller an infinite setpoint was saturated into a motion
    at full speed, without e_emergency; a short one failed deep inside the table encoding."""
    program = Program('qp', 'p')
    topic = program.spg.params.topic
    outcomes = _run_each(program, {'infinite x': [Step(None, None, [math.inf] + [0.0] * 5)],
                                   'three values': [Step(None, None, [0.0] * 3)]})
    for name, outcome in outcomes.items():
        assert any(e.startswith(f'{topic}: setpoint') and e.endswith('is not 6 finite values')
                   for e in outcome.emergencies), (name, outcome.emergencies)
        assert outcome.safety and not any(outcome.commands[-1].velocity), name

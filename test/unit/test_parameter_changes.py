"""Parameters set on a running entity are configuration (issue #14 item 4; paper §5): checked by the
entity's parameter model (the rules of the model file: declared type and range, then the model's
own), and every change or refusal raised as an event naming the entity, the parameter, the old and
the new value, and who set it; a ``ros2 param dump`` of running entities becomes a named
configuration of the model. Real rclpy nodes, no mocks."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
import rclpy
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions

from itasc_bringup.model.dump import configuration_of
from itasc_core.communication.events import EventListener
from itasc_core.entity import CompositeContext
from itasc_tasks.entities import ConstraintControllerEntity

TASK = CompositeContext(name='T', namespace='/changes/T')


@pytest.fixture
def controller():
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    cc = ConstraintControllerEntity('CC', composite=TASK, parameters={'task': 'T', 'kp': 2.0})
    heard: list = []
    EventListener(cc, topics=[TASK.events_topic], immediate=True, on_priority=heard.append)
    yield cc, heard
    cc.destroy_node()
    rclpy.try_shutdown()


def spin(node, until, timeout: float = 5.0) -> None:
    end = time.monotonic() + timeout
    while not until() and time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.05)


@pytest.mark.parametrize('name, value, reason', [
    ('kp', -1.0, 'Parameter kp out of range Min: 0.0, Max: inf, value: -1.0'),
    ('kind', 'p', 'Trying to set a read-only parameter: kind.'),  # another law is another entity (a swap)
    ('max_output', 0.0, 'max_output: Input should be greater than 0'),
    ('kp', 'fast', "Wrong parameter type, expected 'Type.DOUBLE' got 'Type.STRING'"),
    ('kp', float('inf'), 'kp: not a finite number (infinite where it was finite)'),  # rclpy's range allows it
    ('task', 'U', 'Trying to set a read-only parameter: task.'),  # its ports' semantics are made from it
])
def test_a_value_the_model_refuses_is_refused_recorded_and_changes_nothing(controller, name, value, reason):
    cc, heard = controller
    (result,) = cc.set_parameters([Parameter(name, value=value)])
    assert (result.successful, result.reason) == (False, reason)
    assert cc.controller.kp == 2.0 and cc.params.kind == 'pid'
    spin(cc, lambda: heard)
    assert [(e.name, e.source, e.detail) for e in heard] == [
        ('e_CC_parameter_refused', '/changes/T/CC', f'{name} = {value!r}: {reason} (set from outside)')]


def test_a_tasks_structure_is_read_only_on_its_entities():
    """What makes a Task (its outputs, its chain's frames or joints) is not a gain: a Constraint
    Output given other outputs than its Setpoint Generator's would put the Task in Safety at the
    next tick. Another structure is another Task (a composition step)."""
    from itasc_tasks.entities import ConstraintOutputEntity, VKCEntity
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    co = ConstraintOutputEntity('CO', composite=TASK, parameters={'task': 'T', 'outputs': ['x', 'y']})
    vkc = VKCEntity('VKC', composite=TASK, parameters={'task': 'T', 'type': 'cartesian', 'o1': 'a', 'o2': 'b/c'})
    try:
        for entity, name, value in ((co, 'outputs', ['x']), (vkc, 'o1', 'd'), (vkc, 'task', 'U')):
            (result,) = entity.set_parameters([Parameter(name, value=value)])
            assert (result.successful, result.reason) == (False, f'Trying to set a read-only parameter: {name}.')
        assert co.params.outputs == ['x', 'y'] and vkc.params.o1 == 'a'
    finally:
        co.destroy_node()
        vkc.destroy_node()
        rclpy.try_shutdown()


def test_an_empty_read_only_list_is_declared_with_its_value_and_stays_read_only():
    """A Constraint Output of every feature (outputs: []) shows outputs = [] to ros2 param, as any
    other parameter; before, a read-only empty list was left uninitialized (rclpy refused its own
    declaration's value), so ros2 param get failed on it."""
    from itasc_tasks.entities import ConstraintOutputEntity
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    co = ConstraintOutputEntity('CO', composite=TASK, parameters={'task': 'T'})
    try:
        assert (co.get_parameter('outputs').type_, co.get_parameter('outputs').value) == (
            Parameter.Type.STRING_ARRAY, [])
        (result,) = co.set_parameters([Parameter('outputs', value=['x'])])
        assert (result.successful, result.reason) == (False, 'Trying to set a read-only parameter: outputs.')
    finally:
        co.destroy_node()
        rclpy.try_shutdown()


def test_a_change_the_entity_cannot_take_is_refused_and_the_old_one_stays():
    """The parameter model cannot know every rule: a Setpoint Generator learns that its topic is not
    a ROS topic name only when it subscribes. The change is refused with that reason, and the
    entity keeps reading the topic it had; before, the exception left rclpy's post-set callback and
    ended the process (as setting a running Scene's relation to an unknown frame did)."""
    from itasc_tasks.entities import SetpointGeneratorEntity
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    spg = SetpointGeneratorEntity('SPG', composite=TASK, parameters={
        'task': 'T', 'kind': 'topic', 'topic': '/changes/setpoint', 'outputs': ['x']})
    heard: list = []
    EventListener(spg, topics=[TASK.events_topic], immediate=True, on_priority=heard.append)
    try:
        (result,) = spg.set_parameters([Parameter('topic', value='not a topic!')])
        assert not result.successful and 'is not a ROS topic name' in result.reason, result.reason
        assert spg.get_parameter('topic').value == '/changes/setpoint'
        assert spg._subscription.topic_name == '/changes/setpoint'
        (result,) = spg.set_parameters([Parameter('topic', value='/changes/other')])
        assert result.successful and spg._subscription.topic_name == '/changes/other', result.reason
        spin(spg, lambda: len(heard) >= 2)
        assert [e.name for e in heard] == ['e_SPG_parameter_refused', 'e_SPG_parameter_set'], heard
    finally:
        spg.destroy_node()
        rclpy.try_shutdown()


def test_an_entity_that_cannot_go_back_after_a_refused_change_goes_to_safety():
    """If an entity fails to take back its old parameters too, it is not fit to run: Safety, not
    an exception out of rclpy's parameter callback (which would end the process)."""
    from itasc_core.computation.functional_entity import FunctionalEntity
    from itasc_core.computation.parameters import ParameterModel

    class Fragile(FunctionalEntity):
        class Parameters(ParameterModel):
            gain: float = 1.0

        broken = False

        def configure(self, params) -> None:
            if params.gain > 10.0:
                self.broken = True  # e.g. a resource it let go of and cannot get back
            if self.broken:
                raise RuntimeError('out of order')

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    entity = Fragile('Fragile', composite=TASK, parameters={'gain': 1.0})
    heard: list = []
    EventListener(entity, topics=[TASK.events_topic], immediate=True, on_priority=heard.append)
    try:
        (result,) = entity.set_parameters([Parameter('gain', value=20.0)])
        assert (result.successful, result.reason) == (False, 'RuntimeError: out of order')
        spin(entity, lambda: len(heard) >= 2)
        assert [(e.name, e.detail) for e in heard] == [
            ('e_emergency', 'Fragile could not take back its parameters after refusing a change (RuntimeError: '
                            'out of order): RuntimeError: out of order'),
            ('e_Fragile_parameter_refused', 'gain = 20.0: RuntimeError: out of order (set from outside)')], heard
    finally:
        entity.destroy_node()
        rclpy.try_shutdown()


def test_the_scenes_structure_is_read_only_and_placements_are_finite():
    """A running Scene's relations, URDFs and sensed objects are what the Tasks and the Solver were
    built for; an object may move, but not to infinity."""
    from itasc_bringup.apps import load_composition
    from itasc_core.itasc.entities import SceneEntity
    program = load_composition('approach_object').entity('itasc')
    parameters = next(e for e in program.entities if e.name == 'Scene').parameters
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    scene = SceneEntity('Scene', composite=CompositeContext(name='itasc', namespace='/changes/itasc'),
                        parameters=parameters)
    try:
        for name, value in (('relations.ApproachObject.o1', 'nope'), ('robots.panda.urdf', '/elsewhere.urdf'),
                            ('objects.target.sensed', True)):
            (result,) = scene.set_parameters([Parameter(name, value=value)])
            assert (result.successful, result.reason) == (False, f'Trying to set a read-only parameter: {name}.')
        (result,) = scene.set_parameters([Parameter('objects.target.xyz', value=[0.5, math.inf, 0.25])])
        assert not result.successful and 'finite' in result.reason, result.reason
        (result,) = scene.set_parameters([Parameter('objects.target.xyz', value=[0.5, 0.1, 0.25])])
        assert result.successful, result.reason
        scene.scene.update(0.0)
        assert list(scene.scene.pose('target').translation) == pytest.approx([0.5, 0.1, 0.25])
    finally:
        scene.destroy_node()
        rclpy.try_shutdown()


def _approach_object_parameters() -> dict[str, dict]:
    """The parameters of approach_object's entities, by entity name (Driver_panda, Robot_panda, Solver...)."""
    from itasc_bringup.apps import load_composition
    found: dict[str, dict] = {}

    def walk(composite) -> None:
        for entity in composite.entities:
            if hasattr(entity, 'entities'):
                walk(entity)
            else:
                found.setdefault(entity.name, entity.parameters)
    walk(load_composition('approach_object'))
    return found


def test_what_a_robot_is_is_read_only_on_the_driver_the_robot_and_the_solver():
    """A driver's robot, URDF, base and start, the robot entity's URDF, the Solver's joints and the
    ros2_control adapter's joints are what the others were built for: before, the simulated driver
    took such changes and silently did nothing with them."""
    from itasc_core.itasc.entities import RobotEntity, SolverEntity
    from itasc_drivers.pose_sensor import PoseSensor
    from itasc_drivers.ros2_control_adapter import Ros2ControlAdapter
    from itasc_drivers.simulated_robot import SimulatedRobot
    parameters = _approach_object_parameters()
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    context = CompositeContext(name='itasc', namespace='/changes/itasc')
    entities = [SimulatedRobot('Driver_panda', composite=context, parameters=parameters['Driver_panda']),
                RobotEntity('Robot_panda', composite=context, parameters=parameters['Robot_panda']),
                SolverEntity('Solver', composite=context, parameters=parameters['Solver']),
                Ros2ControlAdapter('Adapter', composite=context, parameters={'robot': 'arm', 'joints': ['a', 'b']}),
                PoseSensor('Sensor', composite=context, parameters={'object': 'target'})]
    driver, robot, solver, adapter, sensor = entities
    try:
        for entity, name, value in ((driver, 'robot', 'other'), (driver, 'urdf', '/elsewhere.urdf'),
                                    (driver, 'base', 'planar'), (driver, 'initial.panda_joint4', -1.0),
                                    (robot, 'urdf', '/elsewhere.urdf'), (solver, 'joint_names', ['a']),
                                    (adapter, 'joints', ['b', 'a']), (adapter, 'robot', 'other'),
                                    (sensor, 'object', 'other')):
            (result,) = entity.set_parameters([Parameter(name, value=value)])
            assert (result.successful, result.reason) == (False, f'Trying to set a read-only parameter: {name}.')
    finally:
        for entity in entities:
            entity.destroy_node()
        rclpy.try_shutdown()


def test_a_simulated_drivers_limits_take_effect_while_it_runs():
    """ros2 param set of a simulated driver's velocity_limit slows the simulated robot at once;
    none again gives the URDF's; a list of the wrong length is refused with the reason. Before,
    every change after the start was accepted and ignored."""
    from itasc_core.communication.samples import JointSample
    from itasc_drivers.simulated_robot import SimulatedRobot
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    driver = SimulatedRobot('Driver_panda', composite=CompositeContext(name='itasc', namespace='/changes/itasc'),
                            parameters=_approach_object_parameters()['Driver_panda'])
    try:
        joints, urdf_limit = driver.robot.joint_names, driver.robot.velocity_limit.copy()
        driver.inputs['command'].deliver(
            JointSample(0.0, tuple(joints), np.zeros(len(joints)), velocity=np.full(len(joints), 1.0)), 'test')

        def moved(seconds: float) -> np.ndarray:
            before = driver.robot.positions.copy()
            driver.update(0.0)
            driver.update(seconds)
            driver._last_t = None
            return driver.robot.positions - before
        (result,) = driver.set_parameters([Parameter('velocity_limit', value=[0.1] * len(joints))])
        assert result.successful, result.reason
        assert moved(0.1) == pytest.approx(np.full(len(joints), 0.01))
        (result,) = driver.set_parameters([Parameter('velocity_limit', value=[0.1, 0.1])])
        assert (result.successful, result.reason) == (
            False, f'ValueError: velocity_limit has 2 values for the {len(joints)} joints of panda')
        assert list(driver.robot.velocity_limit) == [0.1] * len(joints)
        (result,) = driver.set_parameters([Parameter('velocity_limit', type_=Parameter.Type.DOUBLE_ARRAY, value=[])])
        assert result.successful, result.reason
        assert list(driver.robot.velocity_limit) == list(urdf_limit)
        assert moved(0.01) == pytest.approx(np.full(len(joints), 0.01))  # 1 rad/s, within the URDF's limits
    finally:
        driver.destroy_node()
        rclpy.try_shutdown()


def test_limits_that_would_move_the_simulated_robot_by_themselves_are_refused():
    """A velocity limit of 0 or below, lower above upper, or limits the robot stands outside while
    it runs: each was accepted, and the next tick moved the robot whatever the Solver commanded
    (-0.5 rad/s on every joint; a jump to the upper limits in one tick). Refused with the reason,
    the robot where it was."""
    from itasc_core.communication.samples import JointSample
    from itasc_drivers.simulated_robot import SimulatedRobot
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    driver = SimulatedRobot('Driver_panda', composite=CompositeContext(name='itasc', namespace='/changes/itasc'),
                            parameters=_approach_object_parameters()['Driver_panda'])
    try:
        joints = driver.robot.joint_names
        n, start = len(joints), driver.robot.positions.copy()
        where = dict(zip(joints, start))
        driver.inputs['command'].deliver(JointSample(0.0, tuple(joints), start, velocity=np.zeros(n)), 'test')
        limits = 'every velocity limit must be > 0 (a limit of 0 or below would move the joint whatever is ' \
                 'commanded, or never)'
        for name, value, reason in [
                ('velocity_limit', [-0.5] * n, f'velocity_limit: Value error, {limits}'),
                ('velocity_limit', [0.0] * n, f'velocity_limit: Value error, {limits}'),
                ('lower', [5.0] * n, 'ValueError: lower is above upper for ' + ', '.join(
                    j for j, hi in zip(joints, driver.robot.upper) if hi < 5.0)),
                ('upper', list(start - 0.1), 'ValueError: the robot is outside the new limits: ' + ', '.join(
                    f'{j} at {where[j]:.4g} (limits [{lo:.4g}, {where[j] - 0.1:.4g}])'
                    for j, lo in zip(joints, driver.robot.lower)))]:
            (result,) = driver.set_parameters([Parameter(name, value=value)])
            assert (result.successful, result.reason) == (False, reason), name
        driver.update(0.0)
        driver.update(0.1)
        assert driver.robot.positions == pytest.approx(start)  # commanded still: still
    finally:
        driver.destroy_node()
        rclpy.try_shutdown()


def test_what_a_tasks_constraint_is_is_read_only_and_its_bounds_are_ordered():
    """``CC.inequality`` set while running turned a 6-D equality Task into bounds of ±inf: the Task
    constrained nothing, its error read 0 and its ``converged`` Monitor fired without the robot
    moving. Read-only now (another constraint is another Task); bounds with lower above upper,
    and Rows weights that are neither one nor one per row (a traceback and Safety at the next
    tick), are refused."""
    from itasc_core.itasc.entities.messages import FeaturesSample
    from itasc_tasks.entities import ConstraintRowsEntity
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    cc = ConstraintControllerEntity('CC', composite=TASK, parameters={'task': 'T', 'inequality': True,
                                                                      'lower': [0.0], 'upper': [1.0]})
    rows = ConstraintRowsEntity('Rows', composite=TASK, parameters={'task': 'T', 'weights': [1.0]})
    try:
        for name, value, reason in [
                ('inequality', False, 'Trying to set a read-only parameter: inequality.'),
                ('lower', [2.0], 'parameters: Value error, lower is above upper (output 0)')]:
            (result,) = cc.set_parameters([Parameter(name, value=value)])
            assert (result.successful, result.reason) == (False, reason), name
        assert cc.inequality and list(cc.lower) == [0.0]
        rows.inputs['output'].deliver(FeaturesSample(0.0, tuple('xyzabc'), ('j1',), np.zeros(6), np.zeros((6, 1))),
                                      'test')
        (result,) = rows.set_parameters([Parameter('weights', value=[1.0, 2.0])])
        assert (result.successful, result.reason) == (
            False, 'ValueError: weights has 2 values for the 6 rows of task T (x, y, z, a, b, c): give one, or '
                   'one per row')
        (result,) = rows.set_parameters([Parameter('weights', value=[1.0, 2.0, 3.0, 4.0, 5.0, 6.0])])
        assert result.successful, result.reason
    finally:
        cc.destroy_node()
        rows.destroy_node()
        rclpy.try_shutdown()


def test_a_ros2_control_adapter_changes_topics_without_losing_the_old_ones_or_what_it_measured():
    """A topic name rclpy refuses leaves the adapter on its topics (before, it had destroyed them
    first and could not go back: Safety); a new command topic keeps what the driver measured,
    so commands go on without waiting for the next joint state."""
    from sensor_msgs.msg import JointState
    from itasc_drivers.ros2_control_adapter import Ros2ControlAdapter
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    adapter = Ros2ControlAdapter('Adapter', composite=CompositeContext(name='itasc', namespace='/changes/itasc'),
                                 parameters={'robot': 'arm', 'joints': ['a', 'b'],
                                             'joint_states_topic': '/changes/joint_states'})
    heard: list = []
    EventListener(adapter, topics=['/changes/itasc/events'], immediate=True, on_priority=heard.append)
    try:
        adapter._on_state(JointState(name=['b', 'a'], position=[2.0, 1.0]))
        subscription, publisher = adapter._state_sub, adapter._publisher
        for name in ('joint_states_topic', 'command_topic'):
            (result,) = adapter.set_parameters([Parameter(name, value='not a topic!')])
            assert not result.successful and 'is not a ROS topic name' in result.reason, result.reason
            assert (adapter._state_sub, adapter._publisher) == (subscription, publisher)
        # both at once, one of them refused: neither changes, not even the one that was fine
        result = adapter.set_parameters_atomically([Parameter('command_topic', value='/changes/elsewhere'),
                                                    Parameter('joint_states_topic', value='not a topic!')])
        assert not result.successful and 'is not a ROS topic name' in result.reason, result.reason
        assert (adapter._state_sub, adapter._publisher) == (subscription, publisher)
        assert adapter._publisher.topic_name == '/velocity_controller/commands'
        spin(adapter, lambda: len(heard) >= 3)
        assert not [e for e in heard if e.name == 'e_emergency'], heard
        (result,) = adapter.set_parameters([Parameter('command_topic', value='/changes/commands')])
        assert result.successful, result.reason
        assert adapter._publisher.topic_name == '/changes/commands' and adapter._state_sub is subscription
        assert list(adapter.measured) == [1.0, 2.0]
        (result,) = adapter.set_parameters([Parameter('joint_states_topic', value='/changes/other_states')])
        assert result.successful and adapter._state_sub.topic_name == '/changes/other_states'
        assert adapter.measured is None  # nothing measured on the new topic yet
    finally:
        adapter.destroy_node()
        rclpy.try_shutdown()


def test_what_a_monitor_watches_and_says_is_read_only_and_its_threshold_takes_effect():
    """A Monitor's field, condition, event and switching events are what the program's FSM was
    checked against (the model names the field of the watched sample and the event a transition
    waits for); before, field = 'bogus' was taken and the next sample put the program in Safety
    (AttributeError), and another event silently left the transition waiting for good."""
    from sensor_msgs.msg import JointState
    from itasc_core.communication.ports import PortSpec
    from itasc_core.computation.monitor import Monitor
    watch = PortSpec(name='joint_state', direction='output', msg_type=JointState, type='joint_state',
                     semantics='JointPositions(arm)', id='/changes/T/Driver/joint_state')
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    monitor = Monitor('far', composite=TASK, watch=watch, parameters={
        'field': 'position[0]', 'condition': 'above', 'threshold': 1.0, 'event': 'e_far'})
    try:
        for name, value in (('field', 'bogus'), ('condition', 'below'), ('event', 'e_other'),
                            ('enable_on', ['e_x']), ('disable_on', ['e_y'])):
            (result,) = monitor.set_parameters([Parameter(name, value=value)])
            assert (result.successful, result.reason) == (False, f'Trying to set a read-only parameter: {name}.')
        (result,) = monitor.set_parameters([Parameter('threshold', value=0.5)])
        assert result.successful, result.reason
        monitor.watch.deliver(JointState(name=['a'], position=[0.7]), 'test')
        monitor.update(0.0)
        assert monitor.raised == 1  # 0.7 is above the new threshold, not the old one
    finally:
        monitor.destroy_node()
        rclpy.try_shutdown()


@pytest.mark.parametrize('entity, values', [
    ('Monitor', {'condition': 'above', 'threshold': math.nan, 'event': 'e_x'}),  # it would never fire
    ('ConstraintControllerEntity', {'lower': [0.0, math.nan]}),
    ('SetpointGeneratorEntity', {'kind': 'fixed', 'value': [math.nan]}),
    ('SolverEntity', {'joint_names': ['a'], 'lower': [math.nan], 'upper': [1.0], 'velocity_limit': [1.0]}),
    ('SceneEntity', {'objects': {'target': {'xyz': [0.5, math.nan, 0.2]}}}),
])
def test_nan_is_never_a_parameter_value(entity, values):
    """rclpy refuses a NaN only where a parameter has a range; the parameter models refuse it
    everywhere, also in lists and nested sections (the rule of the model file)."""
    from itasc_core.computation.monitor import Monitor
    from itasc_core.itasc.entities import SceneEntity, SolverEntity
    from itasc_tasks.entities import ConstraintControllerEntity, SetpointGeneratorEntity
    kinds = {k.__name__: k for k in (Monitor, ConstraintControllerEntity, SetpointGeneratorEntity, SolverEntity,
                                     SceneEntity)}
    with pytest.raises(ValueError, match='NaN is not a value|finite number'):
        kinds[entity].parameters_of(values)


def test_a_change_is_taken_at_once_and_raised_with_old_and_new_value_and_who(controller):
    cc, heard = controller
    result = cc.set_parameters_atomically([Parameter('kp', value=3.0)])  # what ~/set_parameters runs
    assert result.successful, result.reason
    assert cc.controller.kp == 3.0
    with cc.set_by('configuration stiff'):  # as a Configurator applies a named configuration
        cc.set_parameters([Parameter('kp', value=5.0), Parameter('ki', value=0.0)])  # ki unchanged: no event
    spin(cc, lambda: len(heard) >= 2)
    assert [(e.name, e.detail) for e in heard] == [
        ('e_CC_parameter_set', 'kp: 2.0 -> 3.0 (set from outside)'),
        ('e_CC_parameter_set', 'kp: 3.0 -> 5.0 (configuration stiff)')]


def test_a_dump_becomes_the_named_configuration_that_sets_it():
    """``ros2 param dump`` of Configurators (nested, as it writes dotted names, or dotted): the
    controller, weights and priority of a Task, a Monitor's threshold; other entities left out."""
    dump = {
        '/app/itasc/ApproachObject/configurator': {'ros__parameters': {
            'CC': {'kind': 'pid', 'kp': 2.0, 'ki': 0.0, 'kd': 0.0, 'max_integral': float('inf'),
                   'max_output': float('inf'), 'task': 'ApproachObject'},
            'Rows': {'weights': [1.0, 0.5], 'priority': 1, 'task': 'x'},
            'SPG': {'kind': 'fixed', 'pose': {'xyz': [0.0, 0.0, 0.0]}}}},
        '/app/itasc/configurator': {'ros__parameters': {
            'tracking_error.condition': 'above', 'tracking_error.threshold': 0.05, 'Solver.kind': 'qp'}},
    }
    assert configuration_of(dump) == {
        'ApproachObject': {'controller': {'kp': 2.0, 'ki': 0.0, 'kd': 0.0}, 'weights': [1.0, 0.5], 'priority': 1},
        'tracking_error': {'threshold': 0.05}}
    with pytest.raises(ValueError, match="/app/itasc/configurator: a named configuration sets a Task's controller"):
        configuration_of({'/app/itasc/configurator': {'ros__parameters': {'Solver': {'kind': 'qp', 'damping': 0.1}}}})
    with pytest.raises(ValueError, match="ApproachObject/CC: expected the dump of a composite's configurator"):
        configuration_of({'/app/itasc/ApproachObject/CC': {'ros__parameters': {'kind': 'p', 'kp': 2.0}}})


def test_a_monitor_switched_on_by_its_event_stays_on_when_its_threshold_is_tuned():
    """Whether a Monitor runs is the Running sub-FSM's (its ``enable_on``/``disable_on`` events);
    ``enabled`` is only how it starts, or an operator's explicit switch. Before, every parameter
    change re-applied ``enabled``: a threshold tuned while the FSM had switched the Monitor on
    switched it off again (approach_object's ``converged`` tuned in ``hold``: the program never
    left ``hold``)."""
    from sensor_msgs.msg import JointState
    from itasc_core.communication.ports import PortSpec
    from itasc_core.computation.monitor import Monitor
    watch = PortSpec(name='joint_state', direction='output', msg_type=JointState, type='joint_state',
                     semantics='JointPositions(arm)', id='/changes/T/Driver/joint_state')
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    monitor = Monitor('far', composite=TASK, watch=watch, parameters={
        'field': 'position[0]', 'condition': 'above', 'threshold': 1.0, 'event': 'e_far',
        'enabled': False, 'enable_on': ['e_go'], 'disable_on': ['e_halt']})
    try:
        monitor.raise_event('e_go')
        spin(monitor, until=lambda: len(monitor._events) > 0)
        monitor.update(0.0)  # takes the switch
        (result,) = monitor.set_parameters([Parameter('threshold', value=0.5)])
        assert result.successful, result.reason
        monitor.watch.deliver(JointState(name=['a'], position=[0.7]), 'test')
        monitor.update(0.01)
        assert monitor.raised == 1  # on, with the new threshold
        (result,) = monitor.set_parameters([Parameter('enabled', value=False)])  # an operator's switch
        assert result.successful, result.reason
        monitor.watch.deliver(JointState(name=['a'], position=[0.2]), 'test')
        monitor.update(0.02)
        monitor.watch.deliver(JointState(name=['a'], position=[0.9]), 'test')
        monitor.update(0.03)
        assert monitor.raised == 1  # off: the condition starting to hold again raised nothing
    finally:
        monitor.destroy_node()
        rclpy.try_shutdown()


def test_an_infinity_is_refused_where_the_value_was_finite_and_one_the_model_gave_may_stay():
    """A model file holds finite numbers only; set while running, Solver.velocity_limit .inf let the
    Solver command 208 rad/s, regularization .inf made every problem infeasible (Safety blaming a
    Task) and a setpoint's duration .inf froze the robot for good. An infinity the model gave (a
    joint its URDF leaves unbounded, as a mobile base's) stays settable as it is."""
    from itasc_core.itasc.entities import SolverEntity
    from itasc_tasks.entities import SetpointGeneratorEntity
    parameters = _approach_object_parameters()['Solver']
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    context = CompositeContext(name='itasc', namespace='/changes/itasc')
    unbounded = dict(parameters, velocity_limit=[math.inf] + list(parameters['velocity_limit'][1:]))
    solver = SolverEntity('Solver', composite=context, parameters=unbounded)
    spg = SetpointGeneratorEntity('SPG', composite=TASK, parameters={
        'kind': 'minimum_jerk', 'value': [0.0], 'duration': 2.0})
    try:
        limits = list(unbounded['velocity_limit'])
        for entity, name, value in ((solver, 'velocity_limit', [math.inf] * len(limits)),
                                    (solver, 'regularization', math.inf), (spg, 'duration', math.inf)):
            (result,) = entity.set_parameters([Parameter(name, value=value)])
            assert (result.successful, result.reason) == (
                False, f'{name}: not a finite number (infinite where it was finite)')
        assert solver.velocity_limit[1:].tolist() == limits[1:] and spg.params.duration == 2.0
        (result,) = solver.set_parameters([Parameter('velocity_limit', value=[math.inf, *[0.5] * (len(limits) - 1)])])
        assert result.successful, result.reason
        assert solver.velocity_limit[0] == math.inf and solver.velocity_limit[1:].tolist() == [0.5] * (len(limits) - 1)
    finally:
        solver.destroy_node()
        spg.destroy_node()
        rclpy.try_shutdown()


def test_a_monitor_that_raises_safety_is_not_switched_off_from_outside():
    """A Driver's watchdog (Driver_<robot>_silent) switched off with ros2 param set left the
    application Running 14 s after its driver died. A Monitor raising e_emergency is a safety
    function: switched off from outside it is not (a configuration of the model may)."""
    from sensor_msgs.msg import JointState
    from itasc_core.communication.ports import PortSpec
    from itasc_core.computation.monitor import Monitor
    watch = PortSpec(name='joint_state', direction='output', msg_type=JointState, type='joint_state',
                     semantics='JointPositions(arm)', id='/changes/T/Driver/joint_state')
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    watchdog = Monitor('Driver_arm_silent', composite=TASK, watch=watch, parameters={
        'condition': 'stale', 'timeout': 0.25, 'event': 'e_emergency'})
    try:
        (result,) = watchdog.set_parameters([Parameter('enabled', value=False)])
        assert (result.successful, result.reason) == (
            False, 'Driver_arm_silent raises e_emergency: a safety function is not switched off from outside while '
                   'it runs')
        assert watchdog.enabled
        (result,) = watchdog.set_parameters([Parameter('timeout', value=0.5)])
        assert result.successful, result.reason
        with watchdog.set_by('configuration maintenance'):
            (result,) = watchdog.set_parameters([Parameter('enabled', value=False)])
        assert result.successful and not watchdog.enabled
    finally:
        watchdog.destroy_node()
        rclpy.try_shutdown()

"""Task composite math (paper §4.1, §4.2): VKCs, constraint outputs, constraint controllers,
setpoint generators and the rows a TaskComputation hands to the Solver."""

import numpy as np
import pinocchio as pin
import pytest
from conftest import PANDA
from itasc_core.itasc import Object, Robot, Scene, se3
from itasc_tasks.constraint_controller import PController, PIDController
from itasc_tasks.constraint_output import ConstraintOutput
from itasc_tasks.setpoint_generator import (FixedSetpoint, MinimumJerkSetpoint, PeriodicSetpoint,
                                            TopicSetpoint, TrapezoidalSetpoint)
from itasc_tasks.task import TaskComputation
from itasc_tasks.vkc import CartesianVKC, DistanceVKC, JointVKC


@pytest.fixture
def scene(panda):
    obstacle = Object('obstacle', xyz=(0.4, 0.1, 0.5), rpy=(0.3, 0.0, 0.2))
    scene = Scene(robots=[panda], objects=[obstacle])
    panda.set_position_vector(np.array([0.2, -0.3, 0.1, -2.0, 0.3, 1.9, 0.4]))
    scene.update()
    return scene


def _tangent_derivative(scene, feature, h=1e-7):
    """d feature / d qdot_i by central differences along each joint."""
    q = scene.q.copy()
    columns = []
    for i in range(scene.nv):
        values = []
        for sign in (1.0, -1.0):
            dq = np.zeros_like(q)
            dq[i] = sign * h
            scene.set_position_vector(q + dq)
            scene.update()
            values.append(feature())
        columns.append((values[0] - values[1]) / (2 * h))
    scene.set_position_vector(q)
    scene.update()
    return np.column_stack(columns)


def test_cartesian_vkc_features_and_jacobians(scene):
    vkc = CartesianVKC('obstacle', 'panda/ee')
    vkc.compute(scene)
    T = scene.relative_pose('obstacle', 'panda/ee')
    np.testing.assert_allclose(vkc.features, np.r_[T.translation, pin.log3(T.rotation)])
    np.testing.assert_allclose(vkc.jacobian, scene.relative_jacobian('obstacle', 'panda/ee'))

    def position():
        vkc.compute(scene)
        return vkc.features[:3].copy()

    J = vkc.jacobian.copy()
    np.testing.assert_allclose(J[:3], _tangent_derivative(scene, position), atol=1e-6)
    log6 = CartesianVKC('obstacle', 'panda/ee', coordinates='log6')

    def chi():
        log6.compute(scene)
        return log6.features.copy()

    log6.compute(scene)
    np.testing.assert_allclose(log6.features, pin.log6(T).vector)
    np.testing.assert_allclose(log6.jacobian, _tangent_derivative(scene, chi), atol=1e-6)


@pytest.mark.parametrize('normal', [None, (0.0, 0.0, 1.0), (1.0, 1.0, 0.0)])
def test_distance_vkc(scene, normal):
    vkc = DistanceVKC('obstacle', 'panda/ee', normal=normal)
    vkc.compute(scene)
    p = scene.relative_pose('obstacle', 'panda/ee').translation
    expected = np.linalg.norm(p) if normal is None else np.dot(normal, p) / np.linalg.norm(normal)
    assert vkc.features[0] == pytest.approx(expected)

    def distance():
        vkc.compute(scene)
        return vkc.features.copy()

    vkc.compute(scene)
    J = vkc.jacobian.copy()
    np.testing.assert_allclose(J, _tangent_derivative(scene, distance), atol=1e-6)


def test_joint_vkc_selection_and_rebinding(scene):
    vkc = JointVKC(['panda_joint4', 'panda_joint2'])
    vkc.compute(scene)
    np.testing.assert_allclose(vkc.features, [-2.0, -0.3])
    assert vkc.jacobian.shape == (2, 7) and vkc.jacobian[0, 3] == 1 and vkc.jacobian[1, 1] == 1
    posture = JointVKC()
    scene.add_robot(Robot('other', PANDA, prefix='o_'))
    posture.compute(scene)
    vkc.compute(scene)
    assert posture.names == tuple(scene.joint_names) and vkc.jacobian.shape == (2, 14)
    np.testing.assert_array_equal(posture.jacobian, np.eye(14))


def test_constraint_output_selection_combination_rotation(scene):
    vkc = CartesianVKC('obstacle', 'panda/ee')
    vkc.compute(scene)
    co = ConstraintOutput(['z', 'rx', 'ry', 'rz'])
    co.compute(vkc)
    np.testing.assert_allclose(co.y, vkc.features[2:])
    np.testing.assert_allclose(co.jacobian, vkc.jacobian[2:])
    assert co.rotation == slice(1, 4)
    partial = ConstraintOutput(['rz'])
    partial.compute(vkc)
    assert partial.rotation is None
    combined = ConstraintOutput(['x', 'y'], combination=[[1.0, -1.0]])
    combined.compute(vkc)
    assert combined.y[0] == pytest.approx(vkc.features[0] - vkc.features[1])
    np.testing.assert_allclose(combined.jacobian[0], vkc.jacobian[0] - vkc.jacobian[1])
    with pytest.raises(KeyError, match='not among'):
        ConstraintOutput(['distance']).compute(vkc)
    with pytest.raises(ValueError, match='consecutively'):
        ConstraintOutput(['rz', 'ry', 'rx']).compute(vkc)


def test_p_controller_rotation_error_feedforward_saturation():
    cc = PController(kp=2.0, max_output=np.array([1.0, 1.0, 1.0, 0.5, 0.5, 0.5]))
    cc.rotation = slice(3, 6)
    R, Rd = pin.exp3(np.array([0.3, -0.2, 1.0])), pin.exp3(np.array([0.1, 0.4, -2.5]))
    y = np.r_[0.0, 0.0, 0.0, pin.log3(R)]
    yd = np.r_[0.1, 0.0, 3.0, pin.log3(Rd)]
    out = cc(y, yd, np.array([0.05, 0.0, 0.0, 0.0, 0.0, 0.0]), 0.01)
    np.testing.assert_allclose(cc.error[3:], pin.log3(Rd @ R.T))  # not yd - y
    assert out[0] == pytest.approx(0.25) and out[2] == 1.0  # ff + kp e, then saturated
    assert np.all(np.abs(out[3:]) <= 0.5)
    cc.kp = np.array([0.0, 0.0, 0.0, 0.1, 0.1, 0.1])  # switched by a Configurator
    np.testing.assert_allclose(cc(y, yd, 0.0, 0.01)[3:], 0.1 * pin.log3(Rd @ R.T))


def test_pid_integral_anti_windup_and_derivative():
    cc = PIDController(kp=1.0, ki=10.0, kd=0.5, max_output=1.0)
    dt = 0.1
    out = cc(np.array([0.0, 0.0]), np.array([0.02, 5.0]), 0.0, dt)
    assert out[0] == pytest.approx(0.02 + 10 * 0.002) and out[1] == 1.0
    for _ in range(20):
        out = cc(np.array([0.0, 0.0]), np.array([0.02, 5.0]), 0.0, dt)
    assert cc.integral[1] == pytest.approx(0.5)  # frozen once the output saturated
    assert cc.integral[0] == pytest.approx(0.02 * 2.1)
    cc.reset()
    cc.max_output = 10.0
    assert cc(np.array([0.0]), np.array([1.0]), 0.0, dt)[0] == pytest.approx(1.0 + 10 * 0.1)
    out = cc(np.array([0.0]), np.array([0.5]), 0.0, dt)
    assert out[0] == pytest.approx(0.5 + 10 * 0.15 + 0.5 * (-0.5 / dt))


def test_minimum_jerk_vector_time_and_velocity_bounded():
    sp = MinimumJerkSetpoint([1.0, -2.0], duration=2.0)
    sp.start(np.array([0.0, 0.0]), 1.0)
    np.testing.assert_allclose(sp(1.0)[0], [0.0, 0.0])
    value, velocity = sp(2.0)  # half way: s = 0.5, sdot = 1.875 / T
    np.testing.assert_allclose(value, [0.5, -1.0])
    np.testing.assert_allclose(velocity, np.array([1.0, -2.0]) * 1.875 / 2.0)
    np.testing.assert_allclose(sp(3.0)[0], [1.0, -2.0])
    np.testing.assert_allclose(sp(3.0)[1], [0.0, 0.0], atol=1e-12)
    bounded = MinimumJerkSetpoint([1.0, -2.0], max_velocity=[1.0, 0.5])
    bounded.start(np.zeros(2), 0.0)
    assert bounded.period == pytest.approx(1.875 * 4.0)
    peak = max(np.abs(bounded(t)[1]).max(axis=0) for t in np.linspace(0, 8, 801))
    assert peak == pytest.approx(0.5, rel=1e-3)


def test_minimum_jerk_se3_geodesic():
    start, target = se3((0, 0, 0), (0, 0, 0)), se3((0.4, 0.0, 0.2), (0.0, 0.0, 1.2))
    sp = MinimumJerkSetpoint(target, max_velocity=(0.1, 0.3))
    sp.start(start, 0.0)
    assert sp.period == pytest.approx(1.875 * max(np.hypot(0.4, 0.2) / 0.1, 1.2 / 0.3))
    mid, twist = sp(sp.period / 2)
    np.testing.assert_allclose(pin.log3(mid.rotation), [0, 0, 0.6], atol=1e-12)
    np.testing.assert_allclose(mid.translation, [0.2, 0.0, 0.1])
    h = 1e-6  # the twist is [d/dt p; omega] in the setpoint's reference frame
    before, after = sp(sp.period / 3 - h)[0], sp(sp.period / 3 + h)[0]
    _, twist = sp(sp.period / 3)
    np.testing.assert_allclose(twist[:3], (after.translation - before.translation) / (2 * h),
                               atol=1e-7)
    np.testing.assert_allclose(twist[3:], pin.log3(after.rotation @ before.rotation.T) / (2 * h),
                               atol=1e-7)
    assert sp(sp.period + 1.0)[0].isApprox(target)


def test_trapezoidal_limits_and_duration():
    sp = TrapezoidalSetpoint([2.0], max_velocity=1.0, max_acceleration=2.0)
    sp.start(np.zeros(1), 0.0)
    assert sp.period == pytest.approx(2.0 + 0.5)  # 2 m at 1 m/s plus one ramp time
    times = np.linspace(-0.1, 3.0, 3101)
    values = np.array([sp(t)[0][0] for t in times])
    speeds = np.array([sp(t)[1][0] for t in times])
    assert speeds.max() == pytest.approx(1.0) and values[-1] == 2.0
    assert np.abs(np.diff(speeds) / np.diff(times)).max() <= 2.0 + 1e-6
    np.testing.assert_allclose(np.gradient(values, times)[5:-5], speeds[5:-5], atol=2e-3)
    slow = TrapezoidalSetpoint([2.0], max_velocity=1.0, max_acceleration=2.0, duration=5.0)
    slow.start(np.zeros(1), 0.0)
    assert slow.period == 5.0 and slow(5.0)[0][0] == 2.0
    assert slow(2.5)[0][0] == pytest.approx(1.0)


def test_periodic_and_topic_setpoints():
    sp = PeriodicSetpoint(amplitude=[0.1, 0.2], period=2.0, offset=0.5)
    value, velocity = sp(0.5)
    np.testing.assert_allclose(value, [0.6, 0.7])
    np.testing.assert_allclose(velocity, [0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(sp(0.0)[1], [0.1 * np.pi, 0.2 * np.pi])
    topic = TopicSetpoint()
    assert not topic.started
    topic.start(np.array([1.0]), 0.0)  # holds the current output until a message arrives
    np.testing.assert_allclose(topic(0.0)[0], [1.0])
    topic.push([2.0, 3.0], velocity=[0.1, 0.0])
    np.testing.assert_allclose(topic(5.0)[0], [2.0, 3.0])
    np.testing.assert_allclose(topic(5.0)[1], [0.1, 0.0])


def test_task_equality_rows_and_monitoring(scene):
    task = TaskComputation('hand', vkc=CartesianVKC('world', 'panda/ee'),
                           output=ConstraintOutput(['x', 'y', 'z']),
                           controller=PController(kp=2.0), priority=1, weights=[1.0, 2.0, 3.0],
                           setpoint=MinimumJerkSetpoint([0.5, 0.0, 0.4], duration=1.0))
    rows = task.compute(scene, 10.0, 0.01)  # starts the motion from the current output
    p = scene.pose('panda/ee').translation
    np.testing.assert_allclose(task.y_desired, p)
    np.testing.assert_allclose(rows.desired, 0.0, atol=1e-12)
    assert rows.priority == 1 and not rows.inequality and rows.J.shape == (3, 7)
    np.testing.assert_allclose(rows.weights, [1.0, 2.0, 3.0])
    rows = task.compute(scene, 10.5, 0.01)
    ff = (np.array([0.5, 0.0, 0.4]) - p) * 1.875
    np.testing.assert_allclose(rows.desired, ff + 2.0 * task.error)
    assert task.error_norm == pytest.approx(np.linalg.norm(task.y_desired - p))
    task.reset()
    task.compute(scene, 20.0, 0.01)
    np.testing.assert_allclose(task.y_desired, p)  # restarted from the current output


def test_task_inequality_rows(scene):
    task = TaskComputation('avoid', vkc=DistanceVKC('obstacle', 'panda/ee'),
                           controller=PController(kp=5.0), lower=0.5)
    rows = task.compute(scene, 0.0, 0.01)
    d = task.y[0]
    assert rows.inequality and rows.lower[0] == pytest.approx(5.0 * (0.5 - d))
    assert rows.upper[0] == np.inf
    assert task.error_norm == pytest.approx(max(0.0, 0.5 - d))


def test_task_se3_setpoint_and_default_hold(scene):
    target = se3((0.4, 0.2, 0.5), (np.pi, 0.0, 0.3))
    task = TaskComputation('hand', vkc=CartesianVKC('world', 'panda/ee'),
                           setpoint=FixedSetpoint(target), controller=PController(kp=1.0))
    rows = task.compute(scene, 0.0, 0.01)
    T = scene.pose('panda/ee')
    np.testing.assert_allclose(rows.desired[:3], target.translation - T.translation)
    np.testing.assert_allclose(rows.desired[3:], pin.log3(target.rotation @ T.rotation.T))
    hold = TaskComputation('hold', vkc=JointVKC(['panda_joint1']))
    hold.compute(scene, 0.0, 0.01)
    np.testing.assert_allclose(hold.y_desired, [0.2])
    assert isinstance(hold.setpoint, FixedSetpoint)

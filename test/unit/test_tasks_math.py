"""Task composite math (paper §4.1, §4.2): VKCs, constraint outputs, constraint controllers,
setpoint generators and the rows a TaskComputation hands to the Solver."""

import numpy as np
import pinocchio as pin
import pytest
from conftest import PANDA
from itasc_core.itasc import Object, Robot, Scene, se3
from itasc_tasks.constraint_controller import control_error, equality_control, inequality_control
from itasc_tasks.controllers import PController, PIDController
from itasc_tasks.constraint_output import ConstraintOutput
from itasc_tasks.setpoint_generator import (FixedSetpoint, MinimumJerkSetpoint, OutputSetpoint, PeriodicSetpoint,
                                            TopicSetpoint, TrapezoidalSetpoint, start_value)
from itasc_tasks.task import TaskComputation
from itasc_core.itasc.coordinates import features_pose, pose_features
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


def _relation(scene, o1='obstacle', o2='panda/ee'):
    """What a chain between o1 and o2 reads: the relation's pose and Jacobian."""
    return scene.relative_pose(o1, o2), scene.relative_jacobian(o1, o2)


def test_cartesian_vkc_features_and_jacobians(scene):
    vkc = CartesianVKC()
    features, jacobian = vkc(*_relation(scene))
    T = scene.relative_pose('obstacle', 'panda/ee')
    np.testing.assert_allclose(features, np.r_[T.translation, pin.log3(T.rotation)])
    np.testing.assert_allclose(jacobian, scene.relative_jacobian('obstacle', 'panda/ee'))
    assert vkc.rotation == 3
    np.testing.assert_allclose(jacobian[:3], _tangent_derivative(scene, lambda: vkc(*_relation(scene))[0][:3]),
                               atol=1e-6)
    log6 = CartesianVKC(coordinates='log6')
    features, jacobian = log6(*_relation(scene))
    np.testing.assert_allclose(features, pin.log6(T).vector)
    np.testing.assert_allclose(jacobian, _tangent_derivative(scene, lambda: log6(*_relation(scene))[0]), atol=1e-6)
    assert log6.rotation is None


@pytest.mark.parametrize('coordinates', ['xyz_log3', 'log6'])
def test_pose_features_and_back(coordinates):
    pose = se3((0.4, -0.2, 0.5), (2.0, -0.4, 0.9))
    features = pose_features(pose, coordinates=coordinates)
    assert features_pose(features, coordinates=coordinates).isApprox(pose, 1e-12)


@pytest.mark.parametrize('normal', [None, (0.0, 0.0, 1.0), (1.0, 1.0, 0.0)])
def test_distance_vkc(scene, normal):
    """The point-point distance, and the point-plane one of the task type point_plane."""
    from itasc_tasks.task_types.point_plane import PointPlaneVKC
    vkc = DistanceVKC() if normal is None else PointPlaneVKC(normal=normal)
    features, jacobian = vkc(*_relation(scene))
    p = scene.relative_pose('obstacle', 'panda/ee').translation
    expected = np.linalg.norm(p) if normal is None else np.dot(normal, p) / np.linalg.norm(normal)
    assert features[0] == pytest.approx(expected)
    np.testing.assert_allclose(jacobian, _tangent_derivative(scene, lambda: vkc(*_relation(scene))[0]), atol=1e-6)


def test_joint_vkc_selection_and_rebinding(scene):
    vkc = JointVKC(['panda_joint4', 'panda_joint2'])
    features, jacobian = vkc(scene.joint_names, scene.q)
    np.testing.assert_allclose(features, [-2.0, -0.3])
    assert jacobian.shape == (2, 7) and jacobian[0, 3] == 1 and jacobian[1, 1] == 1
    scene.add_robot(Robot('other', PANDA, prefix='o_'))
    features, jacobian = vkc(scene.joint_names, scene.q)
    assert jacobian.shape == (2, 14) and jacobian[0, 3] == 1
    posture = JointVKC(scene.joint_names)
    features, jacobian = posture(scene.joint_names, scene.q)
    np.testing.assert_array_equal(jacobian, np.eye(14))
    np.testing.assert_array_equal(features, scene.q)
    with pytest.raises(KeyError, match='no joints'):
        JointVKC(['nope'])(scene.joint_names, scene.q)


def test_constraint_output_selection_combination_rotation(scene):
    features, jacobian = CartesianVKC()(*_relation(scene))
    names = CartesianVKC.names
    selection = ConstraintOutput(['z', 'rx', 'ry', 'rz']).bind(names, 3)
    y, J = selection(features, jacobian)
    np.testing.assert_allclose(y, features[2:])
    np.testing.assert_allclose(J, jacobian[2:])
    assert selection.rotation == 1 and selection.names == ('z', 'rx', 'ry', 'rz')
    assert ConstraintOutput(['rz']).bind(names, 3).rotation is None
    assert ConstraintOutput().bind(names, None).rotation is None  # log6: no rotation triple
    combined = ConstraintOutput(['x', 'y'], combination=[[1.0, -1.0]]).bind(names, 3)
    y, J = combined(features, jacobian)
    assert y[0] == pytest.approx(features[0] - features[1]) and combined.names == ('y0',)
    np.testing.assert_allclose(J[0], jacobian[0] - jacobian[1])
    with pytest.raises(KeyError, match='not among'):
        ConstraintOutput(['distance']).bind(names, 3)
    with pytest.raises(ValueError, match='consecutively'):
        ConstraintOutput(['rz', 'ry', 'rx']).bind(names, 3)


def test_p_controller_rotation_error_feedforward_saturation():
    cc = PController(kp=2.0, max_output=np.array([1.0, 1.0, 1.0, 0.5, 0.5, 0.5]))
    R, Rd = pin.exp3(np.array([0.3, -0.2, 1.0])), pin.exp3(np.array([0.1, 0.4, -2.5]))
    y = np.r_[0.0, 0.0, 0.0, pin.log3(R)]
    yd = np.r_[0.1, 0.0, 3.0, pin.log3(Rd)]
    out, lower, upper, setpoint, error = equality_control(cc, y, yd, np.array([0.05, 0.0, 0.0, 0.0, 0.0, 0.0]), 0.01,
                                                         rotation=3)
    np.testing.assert_allclose(error[3:], pin.log3(Rd @ R.T))  # not yd - y
    assert out[0] == pytest.approx(0.25) and out[2] == 1.0  # ff + kp e, then saturated
    assert np.all(np.abs(out[3:]) <= 0.5)
    assert lower is out and upper is out and setpoint is yd
    cc.kp = np.array([0.0, 0.0, 0.0, 0.1, 0.1, 0.1])  # switched by a Configurator
    np.testing.assert_allclose(equality_control(cc, y, yd, 0.0, 0.01, rotation=3)[0][3:], 0.1 * pin.log3(Rd @ R.T))
    np.testing.assert_allclose(control_error(y, yd), yd - y)  # no rotation triple: the plain difference


def test_pid_integral_anti_windup_and_derivative():
    cc = PIDController(kp=1.0, ki=10.0, kd=0.5, max_output=1.0)
    dt = 0.1
    out = cc(np.array([0.02, 5.0]), 0.0, dt)
    assert out[0] == pytest.approx(0.02 + 10 * 0.002) and out[1] == 1.0
    for _ in range(20):
        out = cc(np.array([0.02, 5.0]), 0.0, dt)
    assert cc.integral[1] == pytest.approx(0.5)  # frozen once the output saturated
    assert cc.integral[0] == pytest.approx(0.02 * 2.1)
    cc.reset()
    cc.max_output = 10.0
    assert cc(np.array([1.0]), 0.0, dt)[0] == pytest.approx(1.0 + 10 * 0.1)
    out = cc(np.array([0.5]), 0.0, dt)
    assert out[0] == pytest.approx(0.5 + 10 * 0.15 + 0.5 * (-0.5 / dt))


def test_inequality_bound_is_free_inside_the_band_and_pushes_back_beyond_it():
    lower, upper, kp = np.array([0.2, -1.0]), np.array([0.5, 1.0]), 4.0
    desired, low, high, setpoint, error = inequality_control(np.array([0.3, 0.0]), lower=lower, upper=upper, kp=kp)
    np.testing.assert_allclose(error, 0.0)  # inside: no error, the setpoint is y itself
    np.testing.assert_allclose(setpoint, [0.3, 0.0])
    assert np.all(low < 0.0) and np.all(high > 0.0)  # ydot = 0 is allowed
    np.testing.assert_allclose(low, kp * (lower - [0.3, 0.0]))
    np.testing.assert_allclose(desired, 0.0)
    _, low, high, _, error = inequality_control(np.array([0.1, 1.5]), lower=lower, upper=upper, kp=kp)
    np.testing.assert_allclose(error, [0.1, -0.5])  # towards the nearest bound
    assert low[0] == pytest.approx(kp * 0.1) and low[0] > 0.0  # must move up at rate kp
    assert high[1] == pytest.approx(kp * -0.5) and high[1] < 0.0  # must move down
    _, low, high, _, _ = inequality_control(np.array([0.1]), lower=0.15, upper=np.inf, kp=5.0)
    assert low[0] == pytest.approx(5.0 * 0.05) and high[0] == np.inf


def test_an_infinite_bound_stays_no_bound_whatever_the_gain():
    """kp = 0 (``ros2 param set .../CC kp 0`` on a d_min Task) made 0 * inf = NaN of the open side,
    and the Solver went to Safety on non-finite rows; an infinite bound is no bound at any gain."""
    _, low, high, _, _ = inequality_control(np.array([0.3]), lower=0.15, upper=np.inf, kp=0.0)
    assert low[0] == 0.0 and high[0] == np.inf  # may not come closer, may go away
    _, low, high, _, _ = inequality_control(np.array([0.3, 0.1]), lower=np.array([-np.inf, 0.0]),
                                            upper=np.array([0.5, np.inf]), kp=np.array([0.0, 0.0]))
    assert low[0] == -np.inf and high[1] == np.inf and low[1] == 0.0 and high[0] == 0.0

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
    task = TaskComputation('hand', vkc=CartesianVKC(), o1='world', o2='panda/ee',
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
    task = TaskComputation('avoid', vkc=DistanceVKC(), o1='obstacle', o2='panda/ee',
                           controller=PController(kp=5.0), lower=0.5)
    rows = task.compute(scene, 0.0, 0.01)
    d = task.y[0]
    assert rows.inequality and rows.lower[0] == pytest.approx(5.0 * (0.5 - d))
    assert rows.upper[0] == np.inf
    assert task.error_norm == pytest.approx(max(0.0, 0.5 - d))


def test_task_se3_setpoint_and_default_hold(scene):
    target = se3((0.4, 0.2, 0.5), (np.pi, 0.0, 0.3))
    task = TaskComputation('hand', vkc=CartesianVKC(), o1='world', o2='panda/ee',
                           setpoint=FixedSetpoint(target), controller=PController(kp=1.0))
    rows = task.compute(scene, 0.0, 0.01)
    T = scene.pose('panda/ee')
    np.testing.assert_allclose(rows.desired[:3], target.translation - T.translation)
    np.testing.assert_allclose(rows.desired[3:], pin.log3(target.rotation @ T.rotation.T))
    hold = TaskComputation('hold', vkc=JointVKC(['panda_joint1']))
    hold.compute(scene, 0.0, 0.01)
    np.testing.assert_allclose(hold.y_desired, [0.2])
    assert isinstance(hold.setpoint, FixedSetpoint)


@pytest.mark.parametrize('coordinates', ['xyz_log3', 'log6'])
def test_pose_setpoints_in_output_space_and_their_start(scene, coordinates):
    """A pose target reaches the controller in the chain's coordinates, selected by the CO; a
    point-to-point motion to a pose starts from the current pose of o2 in o1."""
    vkc = CartesianVKC(coordinates=coordinates)
    features, _ = vkc(*_relation(scene))
    selection = ConstraintOutput(['x', 'y', 'z']).bind(vkc.names, vkc.rotation)
    target = se3((0.4, 0.2, 0.5), (np.pi, 0.0, 0.3))
    value, velocity = OutputSetpoint()(target, np.arange(6.0), selection=selection, rotation=vkc.rotation)
    np.testing.assert_allclose(value, pose_features(target, coordinates=coordinates)[:3])
    np.testing.assert_allclose(velocity, [0.0, 1.0, 2.0])
    vector = np.array([1.0, 2.0, 3.0])
    assert OutputSetpoint()(vector, vector, selection=selection, rotation=vkc.rotation)[0] is vector
    motion = MinimumJerkSetpoint(target, duration=1.0)
    start = start_value(motion, features=features, output=features[:3], rotation=vkc.rotation)
    assert start.isApprox(scene.relative_pose('obstacle', 'panda/ee'), 1e-12)
    assert start_value(MinimumJerkSetpoint(vector, duration=1.0), features=features, output=vector,
                       rotation=vkc.rotation) is vector


@pytest.mark.parametrize('answer, got', [(np.zeros(8), '8 values'), (0.0, '0.0'), (None, 'None')])
def test_a_control_law_that_returns_the_wrong_shape_is_named_not_the_solver(answer, got):
    """A controller plugin returning 8 values for 6 outputs (or a scalar, or None) reached the Solver,
    whose Safety then read 'shapes (8,) and (6,7) not aligned' or "'float' object has no attribute
    'tolist'": nothing named the law."""
    class Wrong(PController):
        def __call__(self, error, feedforward, dt):
            return answer

    with pytest.raises(TypeError, match=f'constraint controller Wrong returned {got} for 6 outputs: expected an '
                                        'array of 6 values'):
        equality_control(Wrong(kp=1.0), np.zeros(6), np.ones(6), 0.0, 0.01)

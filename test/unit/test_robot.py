"""Robot, Object and Scene (paper §4.1): models from URDF, joint state by name, mobile bases,
object frames, forward kinematics, frame and relative Jacobians (checked by finite differences)."""

import numpy as np
import pinocchio as pin
import pytest
from conftest import PANDA, PANDA_MOBILE
from itasc_core.itasc import Object, Robot, Scene, se3

WHEELED = """<robot name="wheeled">
  <link name="base"/><link name="wheel"/><link name="arm"/>
  <joint name="wheel_joint" type="continuous">
    <parent link="base"/><child link="wheel"/><axis xyz="0 1 0"/>
    <limit effort="1" velocity="4.0"/>
  </joint>
  <joint name="arm_joint" type="revolute">
    <parent link="base"/><child link="arm"/><origin xyz="0 0 0.2"/><axis xyz="0 0 1"/>
    <limit effort="1" lower="-1.0" upper="1.5" velocity="2.0"/>
  </joint>
</robot>"""


def test_panda_model_and_urdf_limits(panda):
    assert panda.nq == panda.nv == 7
    assert panda.joint_names == [f'panda_joint{i}' for i in range(1, 8)]
    assert panda.lower[3] == -3.0718 and panda.upper[3] == -0.0698
    np.testing.assert_array_equal(panda.velocity_limit, [2.175] * 4 + [2.61] * 3)


def test_urdf_string_continuous_joint_and_overrides():
    robot = Robot('w', WHEELED, upper={'arm_joint': 1.2}, velocity_limit={'wheel_joint': 3.0})
    assert robot.nq == 3 and robot.nv == 2  # continuous joint: (cos, sin), one velocity
    wheel, arm = robot.joint_names.index('wheel_joint'), robot.joint_names.index('arm_joint')
    assert robot.lower[wheel] == -np.inf and robot.upper[wheel] == np.inf
    assert robot.lower[arm] == -1.0 and robot.upper[arm] == 1.2
    assert robot.velocity_limit[wheel] == 3.0 and robot.velocity_limit[arm] == 2.0
    robot.set_positions(['arm_joint', 'unknown', 'wheel_joint'], [0.5, 9.0, 3.0])
    assert robot.positions[wheel] == pytest.approx(3.0) and robot.positions[arm] == 0.5
    qdot = np.zeros(2)
    qdot[wheel] = 1.0
    robot.integrate(qdot, 0.5)  # wraps past pi
    assert robot.positions[wheel] == pytest.approx(3.5 - 2 * np.pi)
    with pytest.raises(KeyError, match='no joint'):
        Robot('w', WHEELED, lower={'nope': 0.0})


def test_set_positions_any_order_and_fk(panda):
    q = np.array([0.1, -0.2, 0.3, -1.5, 0.4, 1.2, -0.6])
    names = panda.joint_names[::-1] + ['other_robot_joint']
    panda.set_positions(names, list(q[::-1]) + [42.0])
    np.testing.assert_allclose(panda.positions, q)
    panda.update()
    model = pin.buildModelFromUrdf(str(PANDA))
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    expected = data.oMf[model.getFrameId('panda_hand_tcp')]
    assert panda.frame_pose('ee').isApprox(expected, 1e-12)


def test_object_frame_offset_and_base_placement():
    robot = Robot('arm', PANDA, xyz=(1.0, 2.0, 0.5), rpy=(0.0, 0.0, np.pi / 2))
    robot.add_frame('tool', 'panda_hand_tcp', xyz=(0.0, 0.0, 0.1), rpy=(np.pi, 0.0, 0.0))
    unplaced = Robot('arm', PANDA)
    q = np.array([0.3, 0.2, -0.1, -1.8, 0.2, 1.6, 0.5])
    for r in (robot, unplaced):
        r.set_position_vector(q)
        r.update()
    expected = se3((1.0, 2.0, 0.5), (0.0, 0.0, np.pi / 2)) * unplaced.frame_pose(
        'panda_hand_tcp') * se3((0.0, 0.0, 0.1), (np.pi, 0.0, 0.0))
    assert robot.frame_pose('tool').isApprox(expected, 1e-12)
    with pytest.raises(KeyError):
        robot.add_frame('x', 'no_such_link')


def _numeric_twist(pose_of, q, i, h=1e-7):
    """Finite-difference [dp/dt; omega] (world) of a pose function for qdot = e_i."""
    dq = np.zeros_like(q)
    dq[i] = h
    T0, T1 = pose_of(q - dq), pose_of(q + dq)
    return np.concatenate([(T1.translation - T0.translation) / (2 * h),
                           pin.log3(T1.rotation @ T0.rotation.T) / (2 * h)])


def test_frame_jacobian_matches_finite_differences(panda):
    rng = np.random.default_rng(0)
    q = rng.uniform(panda.lower, panda.upper)

    def pose(qq):
        panda.set_position_vector(qq)
        panda.update()
        return panda.frame_pose('ee')

    pose(q)
    J = panda.frame_jacobian('ee')
    numeric = np.column_stack([_numeric_twist(pose, q, i) for i in range(7)])
    np.testing.assert_allclose(J, numeric, atol=1e-6)


def test_planar_and_free_flyer_bases():
    mobile = Robot('mm', PANDA_MOBILE, base='planar', prefix='mm_', xyz=(1.0, 0.0, 0.0))
    assert mobile.joint_names[:3] == ['mm_base_x', 'mm_base_y', 'mm_base_theta']
    assert mobile.nq == 11 and mobile.nv == 10
    assert np.isinf(mobile.lower[:3]).all() and np.isinf(mobile.velocity_limit[:3]).all()
    mobile.set_positions(['mm_base_theta', 'mm_base_x'], [np.pi / 2, 0.5])
    np.testing.assert_allclose(mobile.positions[:3], [0.5, 0.0, np.pi / 2])
    qdot = np.zeros(10)
    qdot[0] = 1.0  # forward in the base frame, which faces world +y
    mobile.integrate(qdot, 0.2)
    mobile.update()
    np.testing.assert_allclose(mobile.frame_pose('base_link').translation, [1.5, 0.2, 0.0],
                               atol=1e-12)
    flyer = Robot('ff', PANDA, base='free_flyer', prefix='ff_')
    p = np.r_[1.0, 2.0, 3.0, 0.1, -0.2, 0.3, np.zeros(7)]
    flyer.set_position_vector(p)
    np.testing.assert_allclose(flyer.positions, p, atol=1e-12)
    assert flyer.nv == 13


def test_object_fixed_sensor_and_trajectory():
    box = Object('box', xyz=(0.5, 0.0, 0.2))
    box.add_frame('top', xyz=(0.0, 0.0, 0.1))
    np.testing.assert_allclose(box.frame_pose('top').translation, [0.5, 0.0, 0.3])
    box.set_pose(se3((1.0, 1.0, 0.0), (0.0, 0.0, np.pi)))
    np.testing.assert_allclose(box.frame_pose('top').translation, [1.0, 1.0, 0.1])
    moving = Object('moving', trajectory=lambda t: se3((t, 0.0, 0.0)))
    moving.update(2.5)
    np.testing.assert_allclose(moving.frame_pose().translation, [2.5, 0.0, 0.0])


def _two_robot_scene():
    arm = Robot('arm', PANDA, xyz=(0.0, -0.6, 0.0))
    arm.add_frame('ee', 'panda_hand_tcp')
    mobile = Robot('mm', PANDA_MOBILE, base='planar', prefix='mm_', xyz=(0.3, 0.6, 0.0),
                   rpy=(0.0, 0.0, -0.4))
    mobile.add_frame('ee', 'panda_hand_tcp', xyz=(0.0, 0.0, 0.05))
    return Scene(robots=[arm, mobile], objects=[Object('table', xyz=(0.5, 0.0, 0.3))])


@pytest.mark.parametrize('o1,o2', [('arm/ee', 'mm/ee'), ('mm/panda_link3', 'mm/ee'),
                                   ('table', 'arm/ee'), ('mm/ee', 'world')])
def test_relative_jacobian_matches_finite_differences(o1, o2):
    scene = _two_robot_scene()
    rng = np.random.default_rng(1)
    finite = np.isfinite(scene.lower)
    q = np.full(scene.nv, 0.3)
    q[finite] = rng.uniform(scene.lower[finite], scene.upper[finite])

    def rel(qq):  # perturb along the tangent space (planar base velocities are local)
        scene.set_position_vector(q)
        scene.integrate(qq - q, 1.0)
        scene.update()
        return scene.relative_pose(o1, o2)

    T = rel(q)
    J = scene.relative_jacobian(o1, o2)
    Jb = scene.relative_jacobian(o1, o2, expressed='o2')
    numeric = np.column_stack([_numeric_twist(rel, q, i) for i in range(scene.nv)])
    np.testing.assert_allclose(J, numeric, atol=1e-6)
    body = np.vstack([T.rotation.T @ numeric[:3], T.rotation.T @ numeric[3:]])
    np.testing.assert_allclose(Jb, body, atol=1e-6)


def test_scene_joint_vector_and_errors():
    scene = _two_robot_scene()
    assert scene.nv == 17 and scene.joint_names[7:10] == ['mm_base_x', 'mm_base_y',
                                                          'mm_base_theta']
    assert scene.robot_slice('mm') == slice(7, 17)
    scene.set_positions(['panda_joint2', 'mm_panda_joint2'], [0.4, -0.4])
    scene.update()
    assert scene.q[1] == 0.4 and scene.q[11] == -0.4
    with pytest.raises(ValueError, match='already in the Scene'):
        scene.add_robot(Robot('other', PANDA))
    with pytest.raises(KeyError, match='no robot or object'):
        scene.pose('nobody/ee')
    with pytest.raises(KeyError, match='no frame'):
        scene.pose('arm/nothing')
    scene.remove('mm')
    assert scene.nv == 7

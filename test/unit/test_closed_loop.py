"""Closed-loop behaviour of the whole computation (paper §2.2, §4): Scene update -> Task rows ->
Solver -> integrate, at 100 Hz, on the Panda model and a mobile manipulator."""

import numpy as np
import pinocchio as pin
import pytest
from conftest import PANDA, PANDA_MOBILE
from itasc_core.itasc import Object, QpSolver, Robot, Scene, WdlsSolver
from itasc_tasks.controllers import PController
from itasc_tasks.constraint_output import ConstraintOutput
from itasc_tasks.setpoint_generator import FixedSetpoint
from itasc_tasks.task import TaskComputation
from itasc_tasks.vkc import CartesianVKC, DistanceVKC, JointVKC

DT = 0.01
READY = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])


def _run(scene, tasks, solver, seconds, until=None):
    """Integrate the closed loop; returns the number of steps run."""
    for k in range(int(seconds / DT)):
        scene.update(k * DT)
        if until is not None and until():
            return k
        rows = [t.compute(scene, k * DT, DT) for t in tasks]
        result = solver.solve(rows, q=scene.q, lower=scene.lower, upper=scene.upper,
                              velocity_limit=scene.velocity_limit, dt=DT)
        assert np.isfinite(result.qdot).all()
        scene.integrate(result.qdot, DT)
    scene.update(seconds)
    return int(seconds / DT)


def _pose_error(T, target):
    return (np.linalg.norm(T.translation - target.translation),
            np.linalg.norm(pin.log3(T.rotation.T @ target.rotation)))


@pytest.mark.parametrize('solver', [QpSolver(), WdlsSolver()], ids=['qp', 'wdls'])
def test_cartesian_task_reaches_random_targets(panda, solver):
    """10 random starts; each target is the hand pose of a random configuration (reachable)
    up to 0.6 rad per joint away; reached within 1 mm and 0.01 rad."""
    scene = Scene(robots=[panda])
    rng = np.random.default_rng(11)
    inner_lo = 0.8 * panda.lower + 0.2 * panda.upper
    inner_hi = 0.2 * panda.lower + 0.8 * panda.upper
    mid = (panda.lower + panda.upper) / 2
    for _ in range(10):
        start = rng.uniform(inner_lo, inner_hi)
        panda.set_position_vector(np.clip(start + rng.uniform(-0.6, 0.6, 7), inner_lo, inner_hi))
        panda.update()
        target = panda.frame_pose('ee')
        panda.set_position_vector(start)
        tasks = [TaskComputation('hand', vkc=CartesianVKC(), o1='world', o2='panda/ee',
                                 controller=PController(kp=4.0, max_output=1.0),
                                 setpoint=FixedSetpoint(target)),
                 TaskComputation('posture', vkc=JointVKC(scene.joint_names), controller=PController(kp=1.0),
                                 setpoint=FixedSetpoint(mid), priority=1, weights=0.01)]
        _run(scene, tasks, solver, 10.0, until=lambda target=target: max(_pose_error(
            scene.pose('panda/ee'), target)) < 1e-4)
        position, orientation = _pose_error(scene.pose('panda/ee'), target)
        assert position < 1e-3 and orientation < 0.01


@pytest.mark.parametrize('solver', [QpSolver(), WdlsSolver()], ids=['qp', 'wdls'])
def test_inequality_keeps_distance_while_pulled_through_obstacle(panda, solver):
    """The hand is pulled to a point behind an obstacle point lying (almost) on the straight
    path; 'distance >= d_min' at the higher priority keeps it away and it goes around."""
    d_min = 0.12
    panda.set_position_vector(READY)
    panda.update()
    start = panda.frame_pose('ee').translation
    goal = start + np.array([0.0, 0.5, 0.0])
    obstacle = Object('obstacle', xyz=(start + goal) / 2 + np.array([0.0, 0.0, 0.02]))
    scene = Scene(robots=[panda], objects=[obstacle])

    def tasks(avoid: bool):
        pull = TaskComputation('pull', vkc=CartesianVKC(), o1='world', o2='panda/ee',
                               output=ConstraintOutput(['x', 'y', 'z']), priority=1,
                               controller=PController(kp=2.0, max_output=0.3),
                               setpoint=FixedSetpoint(goal))
        posture = TaskComputation('posture', vkc=JointVKC(scene.joint_names), priority=2,
                                  controller=PController(kp=1.0), setpoint=FixedSetpoint(READY))
        keep_away = TaskComputation('avoid', vkc=DistanceVKC(), o1='obstacle', o2='panda/ee',
                                    controller=PController(kp=5.0), lower=d_min)
        return [keep_away, pull, posture] if avoid else [pull, posture]

    closest = []
    for avoid in (False, True):
        panda.set_position_vector(READY)
        distances = []
        _run(scene, tasks(avoid), solver, 8.0, until=lambda distances=distances: distances.append(
            np.linalg.norm(scene.pose('panda/ee').translation - obstacle.frame_pose().translation)))
        closest.append(min(distances))
    assert closest[0] < d_min / 4  # without the inequality the pull goes through it
    assert closest[1] >= d_min - 1e-3
    assert np.linalg.norm(scene.pose('panda/ee').translation - goal) < 0.01  # went around


def test_relative_task_between_two_arms():
    left = Robot('left', PANDA, prefix='left_', xyz=(0.0, -0.45, 0.0), rpy=(0.0, 0.0, 0.6))
    right = Robot('right', PANDA, prefix='right_', xyz=(0.0, 0.45, 0.0), rpy=(0.0, 0.0, -0.6))
    for r in (left, right):
        r.add_frame('ee', 'panda_hand_tcp')
    scene = Scene(robots=[left, right])
    rng = np.random.default_rng(5)
    scene.set_position_vector(np.r_[READY, READY] + rng.uniform(-0.4, 0.4, 14))
    scene.update()
    target = scene.relative_pose('left/ee', 'right/ee')  # reachable by construction
    scene.set_position_vector(np.r_[READY, READY])
    scene.update()
    assert _pose_error(scene.relative_pose('left/ee', 'right/ee'), target)[0] > 0.1
    task = TaskComputation('handover', vkc=CartesianVKC(), o1='left/ee', o2='right/ee',
                           controller=PController(kp=3.0), setpoint=FixedSetpoint(target))
    posture = TaskComputation('posture', vkc=JointVKC(scene.joint_names), priority=1, weights=0.01,
                              setpoint=FixedSetpoint(np.r_[READY, READY]))
    _run(scene, [task, posture], QpSolver(), 6.0)
    position, orientation = _pose_error(scene.relative_pose('left/ee', 'right/ee'), target)
    assert position < 1e-3 and orientation < 0.01
    assert np.abs(scene.q[:7] - READY).max() > 0.05 and np.abs(scene.q[7:] - READY).max() > 0.05


def test_relative_task_arm_and_mobile_manipulator():
    arm = Robot('arm', PANDA)
    mobile = Robot('mm', PANDA_MOBILE, base='planar', prefix='mm_', xyz=(1.4, 0.0, 0.0),
                   rpy=(0.0, 0.0, np.pi),
                   velocity_limit={'mm_base_x': 0.5, 'mm_base_y': 0.5, 'mm_base_theta': 1.0})
    for r in (arm, mobile):
        r.add_frame('ee', 'panda_hand_tcp')
    scene = Scene(robots=[arm, mobile])
    home = np.r_[READY, 0.0, 0.0, 0.0, READY]
    rng = np.random.default_rng(2)
    scene.set_position_vector(home + np.r_[rng.uniform(-0.3, 0.3, 7), -0.4, 0.2, 0.3,
                                           rng.uniform(-0.3, 0.3, 7)])
    scene.update()
    target = scene.relative_pose('arm/ee', 'mm/ee')
    scene.set_position_vector(home)
    task = TaskComputation('meet', vkc=CartesianVKC(), o1='arm/ee', o2='mm/ee',
                           controller=PController(kp=3.0), setpoint=FixedSetpoint(target))
    posture = TaskComputation('posture', vkc=JointVKC(scene.joint_names), priority=1, weights=0.01,
                              setpoint=FixedSetpoint(home))
    _run(scene, [task, posture], QpSolver(), 8.0)
    position, orientation = _pose_error(scene.relative_pose('arm/ee', 'mm/ee'), target)
    assert position < 1e-3 and orientation < 0.01

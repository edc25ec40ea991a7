"""Solvers (paper §2.2, §4.1 "Solver"): WDLS and the QP cascade against closed-form solutions,
pink, joint limits and singularities."""

import numpy as np
import pinocchio as pin
import pytest
from itasc_core.itasc import ConstraintRows, Object, QpSolver, Scene, WdlsSolver
from itasc_tasks.controllers import PController
from itasc_tasks.setpoint_generator import FixedSetpoint
from itasc_tasks.task import TaskComputation
from itasc_tasks.vkc import CartesianVKC, JointVKC

PANDA_READY = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]

INF = np.full(7, np.inf)
# Closed-form comparisons need undamped WDLS: damping starts below s_min = 1e-3 here. Random
# configurations come near singular (s_min ~ 0.007 for the elbow at seed 4), so the QP's
# singularity threshold is 1e-3 too, checked on every step (tests share the solver objects).
SINGULARITY = {'singularity_epsilon': 1e-3, 'singularity_check_period': 1}
SOLVERS = [WdlsSolver(epsilon=1e-3), QpSolver(**SINGULARITY), QpSolver(backend='quadprog', **SINGULARITY),
           QpSolver(direct=False, **SINGULARITY)]
IDS = ['wdls', 'qp-daqp', 'qp-quadprog', 'qp-daqp-via-qpsolvers']


def _solve(solver, rows, n=7, q=None, dt=0.01):
    return solver.solve(rows, q=np.zeros(n) if q is None else q, lower=-INF[:n],
                        upper=INF[:n], velocity_limit=INF[:n], dt=dt)


def _jacobians(panda, seed):
    rng = np.random.default_rng(seed)
    panda.set_position_vector(rng.uniform(panda.lower * 0.7, panda.upper * 0.7))
    panda.update()
    return panda.frame_jacobian('ee'), panda.frame_jacobian('panda_link4'), rng


@pytest.mark.parametrize('solver', SOLVERS, ids=IDS)
@pytest.mark.parametrize('seed', range(5))
def test_strict_priorities_equal_null_space_projection(panda, solver, seed):
    """Level 0: 3-D position of the hand; level 1: a conflicting 6-D twist (3 + 6 > 7 DOF)."""
    J, _, rng = _jacobians(panda, seed)
    J1, J2 = J[:3], J
    y1, y2 = rng.normal(size=3) * 0.2, rng.normal(size=6) * 0.5
    w2 = np.array([1.0, 2.0, 3.0, 0.5, 0.5, 4.0])
    rows = [ConstraintRows.equality('low', J2, y2, priority=1, weights=w2),
            ConstraintRows.equality('high', J1, y1, priority=0)]
    result = _solve(solver, rows)
    J1p = np.linalg.pinv(J1)
    N1 = np.eye(7) - J1p @ J1
    sw = np.sqrt(w2)[:, None]
    expected = J1p @ y1 + np.linalg.pinv(sw * J2 @ N1) @ (sw[:, 0] * (y2 - J2 @ J1p @ y1))
    assert np.abs(J1 @ result.qdot - y1).max() < 1e-6  # higher level met (DAQP primal_tol)
    assert np.abs(J2 @ result.qdot - y2).max() > 1e-3  # lower level really conflicts
    np.testing.assert_allclose(result.qdot, expected, rtol=0, atol=1e-6 * np.abs(expected).max())
    assert result.status == 'ok'


@pytest.mark.parametrize('solver', SOLVERS, ids=IDS)
@pytest.mark.parametrize('seed', range(5))
def test_same_priority_equals_weighted_least_squares(panda, solver, seed):
    """Hand 6-D and elbow 6-D twists (12 rows on 7 DOF) at one level, different weights."""
    Ja, Jb, rng = _jacobians(panda, seed)
    ya, yb = rng.normal(size=6) * 0.3, rng.normal(size=6) * 0.3
    wa, wb = np.full(6, 10.0), np.array([1.0, 1.0, 1.0, 0.1, 0.1, 0.1])
    rows = [ConstraintRows.equality('hand', Ja, ya, weights=wa),
            ConstraintRows.equality('elbow', Jb, yb, weights=wb)]
    result = _solve(solver, rows)
    J, y, w = np.vstack([Ja, Jb]), np.r_[ya, yb], np.r_[wa, wb]
    reg = getattr(solver, 'regularization', 0.0)
    expected = np.linalg.solve(J.T @ (w[:, None] * J) + reg * np.eye(7), J.T @ (w * y))
    np.testing.assert_allclose(result.qdot, expected, rtol=0, atol=1e-8 * np.abs(expected).max())
    assert result.status == 'ok'


def test_pink_cross_check(panda):
    """Frame task + posture task with configuration and velocity limits: our single-level QP
    (weights = cost^2, regularization = pink damping, kp = gain/dt) equals pink.solve_ik."""
    pink = pytest.importorskip('pink')
    from pink.tasks import FrameTask, PostureTask

    target = Object('target')
    scene = Scene(robots=[panda], objects=[target])
    rng = np.random.default_rng(7)
    dt, damping, gains = 0.01, 1e-6, [1.0, 0.05]
    cost = np.array([1.0, 1.0, 1.0, 0.5, 0.5, 0.5])
    posture_cost = 1e-2
    solver = QpSolver(regularization=damping, position_limit_gain=0.5, **SINGULARITY)
    statuses = set()
    for i in range(20):
        gain = gains[i % 2]
        q = rng.uniform(panda.lower, panda.upper)
        q_posture = rng.uniform(panda.lower, panda.upper)
        panda.set_position_vector(q + rng.uniform(-0.3, 0.3, 7) * (i % 2))
        panda.update()
        target.set_pose(panda.frame_pose('ee'))
        panda.set_position_vector(q)
        scene.update()
        configuration = pink.Configuration(panda.model, panda.model.createData(), panda.q)
        frame_task = FrameTask('ee', position_cost=1.0, orientation_cost=0.5, gain=gain)
        frame_task.set_target(target.frame_pose())
        posture_task = PostureTask(cost=posture_cost, gain=gain)
        posture_task.set_target(q_posture)
        v_pink = pink.solve_ik(configuration, [frame_task, posture_task], dt, solver='daqp',
                               damping=damping)
        tasks = [
            TaskComputation('frame', vkc=CartesianVKC(coordinates='log6'), o1='target', o2='panda/ee',
                            controller=PController(kp=gain / dt),
                            setpoint=FixedSetpoint(np.zeros(6)), weights=cost ** 2),
            TaskComputation('posture', vkc=JointVKC(scene.joint_names), controller=PController(kp=gain / dt),
                            setpoint=FixedSetpoint(q_posture), weights=posture_cost ** 2)]
        result = solver.solve([t.compute(scene, 0.0, dt) for t in tasks], q=scene.q,
                              lower=scene.lower, upper=scene.upper,
                              velocity_limit=scene.velocity_limit, dt=dt)
        statuses.add(result.status)
        assert np.linalg.norm(result.qdot - v_pink) <= 1e-6 * np.linalg.norm(v_pink)
    assert statuses == {'ok', 'saturated'}  # both free and limit-bound solutions compared


def test_joint_limits_never_exceeded(panda):
    """10 s at 100 Hz of random hand targets, a third of them out of reach: every q stays
    within its position limits and every |qdot| within its velocity limit."""
    target = Object('target')
    scene = Scene(robots=[panda], objects=[target])
    rng = np.random.default_rng(3)
    mid = (panda.lower + panda.upper) / 2
    panda.set_position_vector(mid)
    scene.update()
    hand = TaskComputation('hand', vkc=CartesianVKC(), o1='world', o2='panda/ee',
                           controller=PController(kp=20.0), setpoint=FixedSetpoint(pin.SE3()))
    posture = TaskComputation('posture', vkc=JointVKC(scene.joint_names), controller=PController(kp=5.0),
                              setpoint=FixedSetpoint(mid), priority=1, weights=0.1)
    solver, dt = QpSolver(), 0.01
    closest = np.inf
    saturated = 0
    for k in range(1000):
        if k % 100 == 0:
            reach = 1.3 if k % 300 == 0 else 0.7
            hand.setpoint = FixedSetpoint(pin.SE3(pin.exp3(rng.normal(size=3)),
                                                  rng.uniform(-reach, reach, 3)))
        scene.update()
        rows = [hand.compute(scene, k * dt, dt), posture.compute(scene, k * dt, dt)]
        result = solver.solve(rows, q=scene.q, lower=scene.lower, upper=scene.upper,
                              velocity_limit=scene.velocity_limit, dt=dt)
        assert np.all(np.abs(result.qdot) <= scene.velocity_limit)
        saturated += result.saturated
        scene.integrate(result.qdot, dt)
        q = panda.positions
        assert np.all(q >= panda.lower) and np.all(q <= panda.upper)
        closest = min(closest, float(np.min(np.minimum(q - panda.lower, panda.upper - q))))
    assert closest < 1e-3 and saturated > 100  # the limits were really reached and active


@pytest.mark.parametrize('solver', SOLVERS[:2], ids=IDS[:2])
def test_velocity_limits_by_scaling_or_bounds(panda, solver):
    J, _, rng = _jacobians(panda, 0)
    rows = [ConstraintRows.equality('fast', J, np.array([5.0, 0, 0, 0, 0, 0]))]
    vmax = np.full(7, 0.5)
    result = solver.solve(rows, q=np.zeros(7), lower=-INF, upper=INF, velocity_limit=vmax,
                          dt=0.01)
    assert result.saturated and result.status == 'saturated'
    assert np.abs(result.qdot).max() == pytest.approx(0.5)
    if isinstance(solver, WdlsSolver):  # uniform scaling keeps the direction
        free = _solve(solver, rows)
        np.testing.assert_allclose(result.qdot / np.abs(result.qdot).max(),
                                   free.qdot / np.abs(free.qdot).max(), atol=1e-12)


def test_wdls_singular_configuration_stays_bounded(panda):
    """Arm stretched (elbow joint at 0, beyond its URDF limit on purpose): asked to move the
    hand along the lost direction, WDLS damps, raises the singular flag, keeps qdot bounded."""
    panda.set_position_vector(np.array([0.0, 0.0, 0.0, -1e-6, 0.0, np.pi / 2, 0.0]))
    panda.update()
    J = panda.frame_jacobian('ee')
    U, s, _ = np.linalg.svd(J)
    assert s[-1] < 1e-5
    lost = 0.1 * U[:, -1]
    undamped = np.linalg.pinv(J) @ lost
    result = _solve(WdlsSolver(), [ConstraintRows.equality('hand', J, lost)])
    assert result.singular and result.status == 'singular'
    assert result.min_singular_value < 1e-5 and result.damping > 0.049
    assert np.isfinite(result.qdot).all()
    assert np.linalg.norm(undamped) > 1e3 and np.linalg.norm(result.qdot) < 0.01
    feasible = 0.1 * U[:, 0]  # a well-conditioned direction is still tracked
    result = _solve(WdlsSolver(), [ConstraintRows.equality('hand', J, feasible)])
    assert np.linalg.norm(J @ result.qdot - feasible) < 1e-3


@pytest.mark.parametrize('solver', SOLVERS[1:], ids=IDS[1:])
def test_qp_reports_a_singular_configuration_and_stays_bounded(panda, solver):
    """The same stretched arm through the QP: status singular, qdot bounded by the joint limits,
    the well-conditioned directions still tracked; and no singular flag away from it."""
    panda.set_position_vector(np.array([0.0, 0.0, 0.0, -1e-6, 0.0, np.pi / 2, 0.0]))
    panda.update()
    J = panda.frame_jacobian('ee')
    U, s, _ = np.linalg.svd(J)
    limits = {'q': np.zeros(7), 'lower': -INF[:7], 'upper': INF[:7], 'velocity_limit': np.full(7, 2.0), 'dt': 0.01}
    result = solver.solve([ConstraintRows.equality('hand', J, 0.1 * U[:, -1])], **limits)
    assert result.singular and result.status == 'singular'
    assert result.min_singular_value < 1e-5 and s[-1] < 1e-5
    assert np.isfinite(result.qdot).all() and np.abs(result.qdot).max() <= 2.0 + 1e-9
    result = solver.solve([ConstraintRows.equality('hand', J, 0.1 * U[:, 0])], **limits)
    assert np.linalg.norm(J @ result.qdot - 0.1 * U[:, 0]) < 1e-3
    panda.set_position_vector(np.array(PANDA_READY))
    panda.update()
    J = panda.frame_jacobian('ee')
    result = solver.solve([ConstraintRows.equality('hand', J, 0.1 * np.ones(6))], **limits)
    assert not result.singular and result.status == 'ok'
    assert result.min_singular_value == pytest.approx(np.linalg.svd(J, compute_uv=False)[-1])


def test_qp_detects_a_singularity_within_its_check_period(panda):
    """The arm reaching a singular pose is reported singular within ``singularity_check_period``
    steps, leaving it is reported within as many, and the value reported is the one measured at
    the arm's pose of the last check (numpy's SVD of the task Jacobian)."""
    period = 3
    solver = QpSolver(singularity_check_period=period)
    limits = {'q': np.zeros(7), 'lower': -INF[:7], 'upper': INF[:7], 'velocity_limit': np.full(7, 2.0), 'dt': 0.01}
    stretched, ready = np.array([0.0, 0.0, 0.0, -1e-6, 0.0, np.pi / 2, 0.0]), np.array(PANDA_READY)
    poses = [ready] * 4 + [stretched] * 4 + [ready] * 4
    singular, measured = [], []
    for q in poses:
        panda.set_position_vector(q)
        panda.update()
        J = panda.frame_jacobian('ee')
        result = solver.solve([ConstraintRows.equality('hand', J, np.zeros(6))], **limits)
        singular.append(result.singular)
        measured.append((result.min_singular_value, np.linalg.svd(J, compute_uv=False)[-1]))
    for change, expected in ((4, True), (8, False)):
        first = next(i for i in range(change, len(poses)) if singular[i] == expected)
        assert first - change < period, (change, singular)
        assert all(s == expected for s in singular[first:change + 4]), singular
    checks = [i for i in range(len(poses)) if i % period == 0]
    for i in checks:  # measured at that step's pose
        assert measured[i][0] == pytest.approx(measured[i][1], rel=1e-9), (i, measured[i])


def test_qp_spreads_the_singularity_checks_of_its_tasks_over_the_period(monkeypatch):
    """Four equality tasks, period 4: each step computes one SVD (not four every fourth step,
    which made those steps a third longer), each task is checked once a period, and the one that
    turns singular is reported within the period, and no longer once it left."""
    from itasc_core.itasc.solver import qp
    svds: list[int] = []
    gesvd = qp._gesvd

    def counted(*args, **kwargs):
        svds[-1] += 1
        return gesvd(*args, **kwargs)
    monkeypatch.setattr(qp, '_gesvd', counted)
    period = 4
    solver = QpSolver(singularity_check_period=period)
    Q = np.linalg.qr(np.random.default_rng(0).normal(size=(7, 7)))[0]
    healthy = {'a': Q[0:2], 'b': Q[2:4], 'c': Q[4:6], 'd': Q[[6, 0]]}
    nearly_parallel = np.array([Q[6], Q[6] + 1e-7 * Q[0]])
    steps = 16
    singular = []
    for step in range(steps):
        svds.append(0)
        tasks = dict(healthy, d=nearly_parallel) if 4 <= step < 10 else healthy
        rows = [ConstraintRows.equality(name, J, np.zeros(2)) for name, J in tasks.items()]
        singular.append(_solve(solver, rows).singular)
    assert svds == [1] * steps, svds
    became = singular.index(True)
    left = singular.index(False, became)
    assert 4 <= became < 4 + period and 10 <= left < 10 + period, singular
    assert all(singular[became:10]) and not any(singular[left:]), singular


@pytest.mark.parametrize('lower, qps', [(-np.inf, 1), (-0.5, 1), (0.2, 2)])
def test_a_top_level_of_inequalities_met_at_rest_is_not_solved(monkeypatch, lower, qps):
    """qdot_0 + qdot_1 in [lower, 1] above a pull towards (1, 1): while the rest point meets the
    row, the step solves one QP (the pull's), not two, and the answer is the cascade's; a row the
    rest point violates (lower 0.2 at qdot = 0) is solved as before."""
    solver = QpSolver()
    calls = []
    daqp = solver._daqp

    def counted(*args):
        calls.append(1)
        return daqp(*args)
    monkeypatch.setattr(solver, '_daqp', counted)
    rows = [ConstraintRows.bounds('sum', np.array([[1.0, 1.0]]), [lower], [1.0]),
            ConstraintRows.equality('pull', np.eye(2), [1.0, 1.0], priority=1)]
    result = _solve(solver, rows, n=2)
    np.testing.assert_allclose(result.qdot, [0.5, 0.5], atol=1e-5)
    assert result.status == 'ok' and len(calls) == qps
    calls.clear()  # joint 1 beyond its limit: the rest point is (0, 0.2), the velocity back
    result = solver.solve(rows, q=np.array([0.0, -1.0]), lower=np.array([-1.0, -0.98]),
                          upper=np.ones(2), velocity_limit=np.ones(2), dt=0.05)
    np.testing.assert_allclose(result.qdot, [0.5, 0.5], atol=1e-5)
    assert len(calls) == 1  # (0, 0.2) meets every row, lower 0.2 too


@pytest.mark.parametrize('solver', SOLVERS, ids=IDS)
def test_infeasible_inequalities_and_bad_input_never_nan(solver):
    e0 = np.eye(3)[:1]
    rows = [ConstraintRows.bounds('above', e0, [1.0], [np.inf]),
            ConstraintRows.bounds('below', e0, [-np.inf], [-1.0])]
    result = _solve(solver, rows, n=3)
    assert result.infeasible and result.status == 'infeasible'
    assert np.isfinite(result.qdot).all()
    bad = [ConstraintRows.equality('nan', np.eye(3), [np.nan, 0.0, 0.0])]
    result = _solve(solver, bad, n=3)
    assert result.status == 'infeasible' and np.isfinite(result.qdot).all()


@pytest.mark.parametrize('solver', SOLVERS + [QpSolver(backend='osqp', **SINGULARITY)], ids=IDS + ['osqp'])
def test_inequality_rows_are_bounds(solver):
    """min |qdot - (1, 1)|^2 s.t. qdot_0 + qdot_1 <= 1 at a higher level: (0.5, 0.5)."""
    rows = [ConstraintRows.bounds('sum', np.array([[1.0, 1.0]]), [-np.inf], [1.0]),
            ConstraintRows.equality('pull', np.eye(2), [1.0, 1.0], priority=1)]
    result = _solve(solver, rows, n=2)
    np.testing.assert_allclose(result.qdot, [0.5, 0.5], atol=1e-5)
    assert result.status == 'ok'

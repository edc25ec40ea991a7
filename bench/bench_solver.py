"""Solver step benchmark (paper §4.1 "Solver"; issue: performance targets).

(a) Panda 7-DOF, 3 tasks (hand frame task, elbow position, posture) with position and velocity
    limits: one full step (Scene update + task rows + solve) for our WDLS and QP cascade with
    every available backend, side by side with pink.solve_ik on the same problem (same rows,
    weights = cost^2, damping, limits, dt), interleaved step by step in the same run.
(b) Talos (38 DOF, free-flyer) from example-robot-data, 6 tasks on 3 priority levels: our step.

Run: python bench/bench_solver.py [--steps N]
"""

from __future__ import annotations

import argparse
import pathlib
import platform
import sys
import time
import warnings

import numpy as np
import pinocchio as pin

ROOT = pathlib.Path(__file__).resolve().parents[1]
for package in ('itasc_core', 'itasc_tasks'):
    sys.path.insert(0, str(ROOT / 'src' / package))

import qpsolvers  # noqa: E402
from itasc_core.itasc import Object, QpSolver, Robot, Scene, WdlsSolver  # noqa: E402
from itasc_tasks.controllers import PController  # noqa: E402
from itasc_tasks.constraint_output import ConstraintOutput  # noqa: E402
from itasc_tasks.setpoint_generator import FixedSetpoint  # noqa: E402
from itasc_tasks.task import TaskComputation  # noqa: E402
from itasc_tasks.vkc import CartesianVKC, JointVKC  # noqa: E402

DT, GAIN, DAMPING = 0.01, 0.5, 1e-8
HAND_COST = np.array([1.0, 1.0, 1.0, 0.5, 0.5, 0.5])
ELBOW_COST, POSTURE_COST = 0.1, 0.01
READY = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])


def machine() -> str:
    model = next((line.split(':', 1)[1].strip() for line in
                  pathlib.Path('/proc/cpuinfo').read_text().splitlines()
                  if line.startswith('model name')), platform.processor() or '?')
    return (f'{model} ({platform.machine()}), Python {platform.python_version()}, '
            f'numpy {np.__version__}, pinocchio {pin.__version__}, qpsolvers '
            f'{qpsolvers.__version__}')


def stats(samples: list[float]) -> str:
    us = np.array(samples) * 1e6
    return (f'median {np.median(us):7.1f}  p90 {np.percentile(us, 90):7.1f}  '
            f'p99 {np.percentile(us, 99):7.1f} us')


def circle(t: float) -> pin.SE3:
    """Moving hand target: a 10 cm circle in front of the ready pose."""
    return pin.SE3(pin.rpy.rpyToMatrix(np.pi, 0.0, 0.0),
                   np.array([0.45, 0.1 * np.cos(t), 0.45 + 0.1 * np.sin(t)]))


def bench_panda(steps: int) -> None:
    import pink
    from pink.tasks import FrameTask, PostureTask

    robot = Robot('panda', ROOT / 'config' / 'robots' / 'panda.urdf')
    robot.add_frame('ee', 'panda_hand_tcp')
    robot.set_position_vector(READY)
    robot.update()
    target = Object('target', trajectory=circle)
    elbow = Object('elbow')
    elbow.set_pose(robot.frame_pose('panda_link4'))
    scene = Scene(robots=[robot], objects=[target, elbow])
    kp = GAIN / DT
    tasks = [
        TaskComputation('hand', vkc=CartesianVKC(coordinates='log6'), o1='target', o2='panda/ee',
                        controller=PController(kp=kp), setpoint=FixedSetpoint(np.zeros(6)),
                        weights=HAND_COST ** 2),
        TaskComputation('elbow', vkc=CartesianVKC(coordinates='log6'), o1='elbow', o2='panda/panda_link4',
                        output=ConstraintOutput(['x', 'y', 'z']), controller=PController(kp=kp),
                        setpoint=FixedSetpoint(np.zeros(3)), weights=ELBOW_COST ** 2),
        TaskComputation('posture', vkc=JointVKC(scene.joint_names), controller=PController(kp=kp),
                        setpoint=FixedSetpoint(READY), weights=POSTURE_COST ** 2)]
    dense = [s for s in ('daqp', 'quadprog', 'proxqp', 'qpalm', 'piqp', 'clarabel', 'highs')
             if s in qpsolvers.available_solvers]
    ours = {'ours WDLS': WdlsSolver(), 'ours QP daqp (direct)': QpSolver(regularization=DAMPING)}
    ours.update({f'ours QP {s} (qpsolvers)': QpSolver(backend=s, direct=False,
                                                      regularization=DAMPING)
                 for s in dense + ['osqp'] if s in qpsolvers.available_solvers})
    configuration = pink.Configuration(robot.model, robot.model.createData(), robot.q)
    hand = FrameTask('ee', position_cost=HAND_COST[:3], orientation_cost=HAND_COST[3:],
                     gain=GAIN)
    elbow_task = FrameTask('panda_link4', position_cost=ELBOW_COST, orientation_cost=0.0,
                           gain=GAIN)
    elbow_task.set_target(elbow.frame_pose())
    posture = PostureTask(cost=POSTURE_COST, gain=GAIN)
    posture.set_target(READY)
    pink_solvers = [s for s in dense + ['osqp'] if s in qpsolvers.available_solvers]
    times: dict[str, list[float]] = {name: [] for name in ours}
    times.update({f'pink {s}': [] for s in pink_solvers})
    deviation: dict[str, float] = dict.fromkeys(times, 0.0)
    osqp_every = 10  # OSQP is ~1 ms: time it on every 10th step to keep the run short
    for k in range(steps + 50):
        t = k * DT
        q = robot.q.copy()
        results = {}
        for name, solver in ours.items():
            if 'osqp' in name and k % osqp_every:
                continue
            robot.q = q.copy()
            t0 = time.perf_counter()
            scene.update(t)
            rows = [task.compute(scene, t, DT) for task in tasks]
            result = solver.solve(rows, q=scene.q, lower=scene.lower, upper=scene.upper,
                                  velocity_limit=scene.velocity_limit, dt=DT)
            elapsed = time.perf_counter() - t0
            results[name] = result.qdot
            if k >= 50:
                times[name].append(elapsed)
        hand.set_target(circle(t))
        for s in pink_solvers:
            if s == 'osqp' and k % osqp_every:
                continue
            t0 = time.perf_counter()
            configuration.update(q)
            v = pink.solve_ik(configuration, [hand, elbow_task, posture], DT, solver=s,
                              damping=DAMPING, safety_break=False)
            elapsed = time.perf_counter() - t0
            results[f'pink {s}'] = v
            if k >= 50:
                times[f'pink {s}'].append(elapsed)
        reference = results['pink daqp']
        for name, v in results.items():
            deviation[name] = max(deviation[name], float(
                np.linalg.norm(v - reference) / max(np.linalg.norm(reference), 1e-9)))
        robot.q = pin.integrate(robot.model, q, results['ours QP daqp (direct)'] * DT)
    print(f'(a) Panda 7 DOF, 3 tasks (16 rows) + position/velocity limits, dt={DT}, '
          f'{steps} steps (OSQP: every {osqp_every}th), interleaved')
    print('    max |qdot - pink daqp| / |pink daqp| in brackets (WDLS: no limits in the '
          'problem, different by design)')
    for name, samples in times.items():
        print(f'  {name:34s} {stats(samples)}  [{deviation[name]:.1e}]')


def bench_talos(steps: int) -> None:
    try:
        import example_robot_data
    except ImportError:
        print('(b) skipped: example-robot-data is not installed '
              '(pip install example-robot-data-loaders example-robot-data)')
        return
    wrapper = example_robot_data.load('talos')
    robot = Robot('talos', wrapper.urdf, base='free_flyer')
    robot.q = wrapper.q0.copy()
    robot.update()
    feet = [Object(f'{side}_foot_target') for side in ('left', 'right')]
    hands = [Object(f'{side}_hand_target') for side in ('left', 'right')]
    for obj, frame in zip(feet + hands, ['left_sole_link', 'right_sole_link',
                                         'gripper_left_base_link', 'gripper_right_base_link']):
        obj.set_pose(robot.frame_pose(frame))
    for obj in hands:
        obj.trajectory = (lambda start: lambda t: start * pin.SE3(
            np.eye(3), np.array([0.05 * np.sin(t), 0.0, 0.05 * np.cos(t)])))(obj.frame_pose())
    scene = Scene(robots=[robot], objects=feet + hands)
    joints = robot.joint_names[6:]
    q0 = scene.q[6:].copy()
    tasks = [TaskComputation(f'{obj.name}', vkc=CartesianVKC(), o1=obj.name, o2=f'talos/{frame}',
                             controller=PController(kp=10.0), priority=priority,
                             setpoint=FixedSetpoint(pin.SE3.Identity()))
             for obj, frame, priority in zip(
                 feet + hands, ['left_sole_link', 'right_sole_link', 'gripper_left_base_link',
                                'gripper_right_base_link'], [0, 0, 1, 1])]
    tasks.append(TaskComputation('torso', vkc=CartesianVKC(), o1='world', o2='talos/torso_2_link',
                                 output=ConstraintOutput(['rx', 'ry', 'rz']), priority=1,
                                 weights=0.1, setpoint=FixedSetpoint(
                                     scene.relative_pose('world', 'talos/torso_2_link'))))
    tasks.append(TaskComputation('posture', vkc=JointVKC(joints), priority=2,
                                 setpoint=FixedSetpoint(q0), weights=0.01))
    print(f'(b) Talos {robot.nv} DOF (free-flyer), 6 tasks (feet | hands + torso | posture, '
          f'{sum(t.compute(scene, 0.0, DT).J.shape[0] for t in tasks)} rows, 3 levels), '
          f'limits, dt={DT}, {steps} steps')
    for name, solver in [('ours WDLS', WdlsSolver()), ('ours QP daqp (direct)', QpSolver()),
                         ('ours QP daqp (qpsolvers)', QpSolver(direct=False))]:
        robot.q = wrapper.q0.copy()
        samples, statuses = [], set()
        for k in range(steps + 50):
            t0 = time.perf_counter()
            scene.update(k * DT)
            rows = [task.compute(scene, k * DT, DT) for task in tasks]
            result = solver.solve(rows, q=scene.q, lower=scene.lower, upper=scene.upper,
                                  velocity_limit=scene.velocity_limit, dt=DT)
            if k >= 50:
                samples.append(time.perf_counter() - t0)
            statuses.add(result.status)
            scene.integrate(result.qdot, DT)
        print(f'  {name:34s} {stats(samples)}  statuses {sorted(statuses)}')


def main() -> None:
    warnings.filterwarnings('ignore', message='Converted matrix')  # pink builds dense for OSQP
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--steps', type=int, default=2000)
    steps = parser.parse_args().steps
    print(f'machine: {machine()}')
    bench_panda(steps)
    bench_talos(steps)


if __name__ == '__main__':
    main()

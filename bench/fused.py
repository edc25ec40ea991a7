"""The constraint-based program of an application as one plain computation (paper §2.2, §4.1): the
Scene, the Tasks active in the initial state of the Running sub-FSM and the Solver, with no
entities, ports or messages in between. The benchmarks time its step as "the solver step alone"
(Scene update + every Task's rows + the solve, what any implementation has to compute) and the
hand-written node (:mod:`handwritten`) runs it.

    program = FusedProgram.of(load_application(path))
    qdot = program.step(q, t, dt)
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from itasc_core.itasc import Object, QpSolver, Robot, Scene, WdlsSolver
from itasc_core.itasc.objects import periodic_translation
from itasc_tasks.controllers import CONTROLLERS
from itasc_tasks.constraint_output import ConstraintOutput
from itasc_tasks.setpoints import SETPOINTS
from itasc_tasks.task import TaskComputation

__all__ = ['FusedProgram']


def _setpoint(task):
    sp = task.setpoint
    return None if sp is None else SETPOINTS[sp.kind].generator(sp)  # None: TaskComputation holds


def _task(task) -> TaskComputation:
    relation = {'o1': task.o1, 'o2': task.o2} if task.kind.reads == 'relation' else {}
    c = task.controller
    controller = CONTROLLERS[c.kind]()
    controller.configure(c)
    inequality = task.constraint == 'inequality'
    return TaskComputation(
        task.name, vkc=task.kind.chain(task), **relation,
        output=ConstraintOutput(list(task.outputs)) if task.outputs else None,
        controller=controller, setpoint=None if inequality else _setpoint(task), priority=task.priority,
        weights=task.weights if len(task.weights) > 1 else task.weights[0],
        lower=(task.d_min if task.d_min is None or len(task.d_min) > 1 else task.d_min[0]) if inequality else None,
        upper=(task.d_max if task.d_max is None or len(task.d_max) > 1 else task.d_max[0]) if inequality else None)


@dataclass
class FusedProgram:
    """Scene, active Tasks and Solver of an application's program, stepped in one call."""

    scene: Scene
    tasks: list[TaskComputation]
    solver: QpSolver | WdlsSolver
    joint_names: list[str]
    initial: np.ndarray

    @classmethod
    def of(cls, app) -> 'FusedProgram':
        """From a checked application model (``itasc_bringup.model.load_application``)."""
        program = app.program
        scene = Scene()
        for r in program.robots:
            robot = Robot(r.name, r.urdf, base=r.base, xyz=r.xyz, rpy=r.rpy)
            for f in r.frames:
                robot.add_frame(f.name, f.link, xyz=f.xyz, rpy=f.rpy)
            for joint, limits in r.limits.items():
                i = robot.joint_names.index(joint)
                for key, value in (('lower', limits.lower), ('upper', limits.upper),
                                   ('velocity_limit', limits.velocity)):
                    if value is not None:
                        getattr(robot, key)[i] = value
            driver = next((d for d in app.drivers if d.robot == r.name), None)
            if driver is not None and getattr(driver, 'initial', None):
                robot.set_positions(list(driver.initial), [float(v) for v in driver.initial.values()])
            scene.add_robot(robot)
        for o in program.objects:
            trajectory = None if o.motion is None else periodic_translation(
                xyz=o.xyz, rpy=o.rpy, amplitude=o.motion.amplitude, period=o.motion.period)
            obj = Object(o.name, xyz=o.xyz, rpy=o.rpy, trajectory=trajectory)
            for f in o.frames:
                obj.add_frame(f.name, xyz=f.xyz, rpy=f.rpy)
            scene.add_object(obj)
        fsm = program.running
        active = fsm.states[fsm.initial].tasks if fsm is not None else None
        tasks = [_task(t) for t in program.tasks if active is None or t.name in active]
        s = program.solver
        joints = list(scene.joint_names)
        weights = np.array([s.joint_weights.get(j, 1.0) for j in joints])
        if s.kind == 'qp':
            solver = QpSolver(backend=s.backend, regularization=s.regularization, joint_weights=weights,
                              position_limit_gain=s.position_limit_gain)
        else:
            solver = WdlsSolver(max_damping=s.damping, joint_weights=weights,
                                position_limit_gain=s.position_limit_gain)
        scene.update(0.0)
        return cls(scene, tasks, solver, joints, scene.q.copy())

    def step(self, q: np.ndarray, t: float, dt: float) -> np.ndarray:
        """Joint velocities for joint positions ``q`` (Scene order) at time ``t``."""
        scene = self.scene
        scene.set_position_vector(q)
        scene.update(t)
        rows = [task.compute(scene, t, dt) for task in self.tasks]
        return self.solver.solve(rows, q=scene.q, lower=scene.lower, upper=scene.upper,
                                 velocity_limit=scene.velocity_limit, dt=dt).qdot

    def time_steps(self, *, steps: int, dt: float, paced: bool = False) -> tuple[list[float], list[float]]:
        """Run ``steps`` closed-loop steps (the joints integrated kinematically); the seconds each
        full step and each solve alone took. ``paced``: one step every ``dt`` seconds, sleeping in
        between as a control loop's timer does, instead of back to back."""
        q = self.initial.copy()
        full, solve = [], []
        scene = self.scene
        due = time.monotonic()
        for k in range(steps):
            if paced:
                due += dt
                time.sleep(max(0.0, due - time.monotonic()))
            t = k * dt
            start = time.perf_counter()
            scene.set_position_vector(q)
            scene.update(t)
            rows = [task.compute(scene, t, dt) for task in self.tasks]
            result = self.solver.solve(rows, q=scene.q, lower=scene.lower, upper=scene.upper,
                                       velocity_limit=scene.velocity_limit, dt=dt)
            full.append(time.perf_counter() - start)
            solve.append(result.solve_time)
            scene.integrate(result.qdot, dt)
            q = scene.q.copy()
        return full, solve

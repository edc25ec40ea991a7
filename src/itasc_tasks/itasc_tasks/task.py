"""TaskComputation: one Task composite (paper §4.2 "Task", Fig. 2) computed in one call on a Scene:
VKC -> CO -> CC with its Setpoint Generator, producing the Task's ``ConstraintRows`` for the Solver.

It reads the Scene where the Task's entities read the Scene entity's ports (the relation between o1
and o2, or the joint positions) and calls the same functions as those entities
(:mod:`itasc_tasks.vkc`, :mod:`~itasc_tasks.constraint_output`, :mod:`~itasc_tasks.setpoint_generator`,
:mod:`~itasc_tasks.constraint_controller`). Equality task: ``J_y qdot = ydot_d``; inequality task
(``lower`` and/or ``upper`` on y given): ``J_y qdot`` within the controller's bounds on ydot.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from itasc_core.itasc.scene import Scene
from itasc_core.itasc.solver.problem import ConstraintRows

from .constraint_controller import equality_control, inequality_control
from .controllers import ConstraintController, PController
from .constraint_output import ConstraintOutput
from .setpoint_generator import HoldSetpoint, OutputSetpoint, PointToPoint, SetpointGenerator, start_value
from .vkc import JointChain, VirtualKinematicChain

__all__ = ['TaskComputation']


class TaskComputation:
    """One Task: VKC, CO, CC and Setpoint Generator, to constraint rows."""

    def __init__(self, name: str, *, vkc: VirtualKinematicChain | JointChain, o1: str | None = None,
                 o2: str | None = None, output: ConstraintOutput | None = None,
                 controller: ConstraintController | None = None, setpoint: SetpointGenerator | None = None,
                 priority: int = 0, weights: float | Sequence[float] = 1.0,
                 lower: float | Sequence[float] | None = None,
                 upper: float | Sequence[float] | None = None) -> None:
        """``vkc`` reads the relation between the object frames ``o1`` and ``o2`` (both given) or, a
        joint chain, the joint positions (neither given). ``output`` defaults to all features,
        ``controller`` to ``PController()``, ``setpoint`` to holding the output where the Task starts
        (equality tasks). ``weights`` (scalar or per output row) and ``priority`` (0 = highest) go to
        the Solver; giving ``lower``/``upper`` (bounds on y) makes this an inequality task."""
        if (o1 is None) != (o2 is None):
            raise ValueError(f'task {name}: give both o1 and o2 (a relation) or neither (joints)')
        self.name = name
        self.vkc, self.o1, self.o2 = vkc, o1, o2
        self.output = output or ConstraintOutput()
        self.controller: ConstraintController = controller or PController()
        self.inequality = lower is not None or upper is not None
        self.setpoint: SetpointGenerator = setpoint or HoldSetpoint()
        self.priority = priority
        self.weights = weights  # may be switched by a Configurator
        self._weights: object = None
        self._output_setpoint = OutputSetpoint()
        self.lower = -np.inf if lower is None else np.asarray(lower, dtype=float)
        self.upper = np.inf if upper is None else np.asarray(upper, dtype=float)
        self.y = np.zeros(0)
        self.y_desired = np.zeros(0)
        self.error = np.zeros(0)
        self.error_norm = 0.0
        empty = np.zeros(0)
        self.rows = ConstraintRows(name, priority, np.zeros((0, 0)), empty, empty, empty, empty,
                                   inequality=self.inequality)

    def reset(self) -> None:
        """Restart: point-to-point setpoints start again from the current output, CC state
        cleared (call when the Task is (re)activated)."""
        if isinstance(self.setpoint, PointToPoint):
            self.setpoint.restart()
        self.controller.reset()

    def compute(self, scene: Scene, t: float, dt: float) -> ConstraintRows:
        """Evaluate the Task for the Scene's current state at time t (cycle time dt)."""
        vkc, o1, o2 = self.vkc, self.o1, self.o2
        if o1 is None or o2 is None:
            features, jacobian = vkc(scene.joint_names, scene.q)
        else:
            features, jacobian = vkc(scene.relative_pose(o1, o2), scene.relative_jacobian(o1, o2))
        selection = self.output.bind(vkc.names, vkc.rotation)
        y, J = selection(features, jacobian)
        self.y = y
        if self.inequality:
            control = inequality_control(y, lower=self.lower, upper=self.upper, kp=self.controller.kp)
        else:
            if not self.setpoint.started:
                self.setpoint.start(start_value(self.setpoint, features=features, output=y, rotation=vkc.rotation), t)
            value, feedforward = self.setpoint(t)
            value, feedforward = self._output_setpoint(value, feedforward, selection=selection, rotation=vkc.rotation)
            control = equality_control(self.controller, y, value, feedforward, dt, rotation=selection.rotation)
        rows = self.rows
        rows.desired, rows.lower, rows.upper, self.y_desired, self.error = control
        self.error_norm = math.sqrt(self.error.dot(self.error))
        rows.priority = self.priority
        rows.J = J
        if rows.weights.shape != y.shape or self._weights is not self.weights:
            rows.weights = np.broadcast_to(np.asarray(self.weights, dtype=float), y.shape).copy()
            self._weights = self.weights
        return rows

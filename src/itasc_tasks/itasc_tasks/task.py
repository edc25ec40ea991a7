"""TaskComputation: the math of one Task composite (paper §4.2 "Task", Fig. 2): VKC -> CO -> CC
with its Setpoint generator, producing the Task's ``ConstraintRows`` for the Solver.

Equality task: ``J_y qdot = ydot_d`` with ``ydot_d = CC(y, y_d, ff)``. Inequality task (``lower``
and/or ``upper`` on y given): ``kp (lower - y) <= J_y qdot <= kp (upper - y)`` with the
controller's ``kp`` (e.g. distance >= d_min gives ``ddot >= kp (d_min - d)``), so a violated
bound is recovered at rate kp and a satisfied one is approached no faster than exponentially.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pinocchio as pin
from itasc_core.itasc.scene import Scene
from itasc_core.itasc.solver.problem import ConstraintRows

from .constraint_controller import PController
from .constraint_output import ConstraintOutput
from .setpoint_generator import FixedSetpoint, SetpointGenerator
from .vkc import CartesianVKC, DistanceVKC, JointVKC

__all__ = ['TaskComputation']


class TaskComputation:
    """One Task: VKC, CO, CC and Setpoint generator, to constraint rows."""

    def __init__(self, name: str, *, vkc: CartesianVKC | DistanceVKC | JointVKC,
                 output: ConstraintOutput | None = None, controller: PController | None = None,
                 setpoint: SetpointGenerator | None = None, priority: int = 0,
                 weights: float | Sequence[float] = 1.0,
                 lower: float | Sequence[float] | None = None,
                 upper: float | Sequence[float] | None = None) -> None:
        """``output`` defaults to all features, ``controller`` to ``PController()``,
        ``setpoint`` to holding the output at its first value (equality tasks).
        ``weights`` (scalar or per output row) and ``priority`` (0 = highest) go to the Solver;
        giving ``lower``/``upper`` (bounds on y) makes this an inequality task."""
        self.name = name
        self.vkc = vkc
        self.output = output or ConstraintOutput()
        self.controller = controller or PController()
        self.inequality = lower is not None or upper is not None
        self.setpoint = setpoint
        self.priority = priority
        self.weights = weights  # may be switched by a Configurator
        self._weights: object = None
        self._pose_setpoint: tuple[object, np.ndarray] = (None, np.zeros(0))
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
        if hasattr(self.setpoint, 'retarget'):
            self.setpoint.retarget(self.setpoint.target)
        self.controller.reset()

    def compute(self, scene: Scene, t: float, dt: float) -> ConstraintRows:
        """Evaluate the Task for the Scene's current state at time t (cycle time dt)."""
        self.vkc.compute(scene)
        self.output.compute(self.vkc)
        y = self.y = self.output.y
        rows = self.rows
        if self.inequality:
            kp = self.controller.kp
            rows.lower = kp * (self.lower - y)
            rows.upper = kp * (self.upper - y)
            rows.desired = np.zeros_like(y)
            self.y_desired = np.clip(y, self.lower, self.upper)
            self.error = self.y_desired - y
        else:
            if self.setpoint is None:
                self.setpoint = FixedSetpoint(y)
            elif not self.setpoint.started:
                se3 = isinstance(getattr(self.setpoint, 'target', None), pin.SE3)
                self.setpoint.start(self.vkc.pose if se3 else y, t)
            value, feedforward = self.setpoint(t)
            if isinstance(value, pin.SE3):
                if value is not self._pose_setpoint[0]:  # a fixed target: convert once
                    self._pose_setpoint = (value, self.vkc.features_of(value))
                value = self.output.select(self._pose_setpoint[1])
                feedforward = self.output.select(feedforward)
            self.y_desired = value
            self.controller.rotation = self.output.rotation
            rows.desired = rows.lower = rows.upper = self.controller(y, value, feedforward, dt)
            self.error = self.controller.error
        self.error_norm = math.sqrt(float(self.error @ self.error))
        rows.priority = self.priority
        rows.J = self.output.jacobian
        if rows.weights.shape != y.shape or self._weights is not self.weights:
            rows.weights = np.broadcast_to(np.asarray(self.weights, dtype=float), y.shape).copy()
            self._weights = self.weights
        return rows

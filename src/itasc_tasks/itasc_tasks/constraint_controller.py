"""Constraint Controllers (paper §4.1 "CC"): the control law that turns an output y and its
setpoint y_d into the desired output velocity for the velocity-resolved Solver::

    ydot_d = sat(ff + kp e + ki int(e) + kd de/dt),   saturated per component at max_output

Error convention: ``e = y_d - y``, except for a complete rotation triple (``rotation`` slice,
set from the Constraint Output of a ``CartesianVKC`` in ``xyz_log3`` coordinates) where
``e = log3(R_d R^T)``, R = exp3(y[rotation]): the rotation from the current to the desired
orientation, expressed in o1, matching the VKC's angular-velocity rows, so ``omega = kp e``
turns along the geodesic. A lone rotation component (e.g. ``['rz']``) uses the plain difference,
exact for rotations about that single axis (a mobile base's heading).

Gains are plain attributes (``kp``, ``ki``, ``kd``, ``max_output``; scalars or vectors) so a
Configurator can switch them between named configurations (e.g. ``high_accuracy_control``).
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

__all__ = ['PController', 'PIDController']


class PController:
    """Proportional control with feed-forward and output saturation."""

    def __init__(self, *, kp: float | np.ndarray = 1.0,
                 max_output: float | np.ndarray = math.inf) -> None:
        self.kp = kp
        self.max_output = max_output
        self.rotation: slice | None = None
        self.error = np.zeros(0)
        self.output = np.zeros(0)

    def compute_error(self, y: np.ndarray, y_desired: np.ndarray) -> np.ndarray:
        e = y_desired - y
        if self.rotation is not None:
            r = self.rotation
            e[r] = pin.log3(pin.exp3(y_desired[r]) @ pin.exp3(y[r]).T)
        return e

    def _law(self, e: np.ndarray, dt: float) -> np.ndarray:
        return self.kp * e

    def __call__(self, y: np.ndarray, y_desired: np.ndarray, feedforward: np.ndarray | float,
                 dt: float) -> np.ndarray:
        """Desired output velocity for output y, setpoint y_desired and its feed-forward."""
        self.error = self.compute_error(y, y_desired)
        out = feedforward + self._law(self.error, dt)
        limit = self.max_output
        if not (isinstance(limit, float) and math.isinf(limit)):
            out = np.minimum(np.maximum(out, -np.asarray(limit)), limit)
        self.output = out
        return out

    def reset(self) -> None:
        """Forget internal state (nothing for P)."""


class PIDController(PController):
    """PID with feed-forward, output saturation and anti-windup: the integral is clamped to
    ``max_integral`` and frozen on components whose output saturated; the derivative is the
    finite difference of the error (zero on the first call after ``reset``)."""

    def __init__(self, *, kp: float | np.ndarray = 1.0, ki: float | np.ndarray = 0.0,
                 kd: float | np.ndarray = 0.0, max_output: float | np.ndarray = math.inf,
                 max_integral: float | np.ndarray = math.inf) -> None:
        super().__init__(kp=kp, max_output=max_output)
        self.ki, self.kd, self.max_integral = ki, kd, max_integral
        self.integral: np.ndarray | None = None
        self._previous: np.ndarray | None = None

    def _law(self, e: np.ndarray, dt: float) -> np.ndarray:
        if self.integral is None or self.integral.shape != e.shape:
            self.integral = np.zeros_like(e)
        free = np.abs(self.output) < self.max_output if self.output.shape == e.shape else True
        self.integral = np.clip(self.integral + np.where(free, e * dt, 0.0),
                                -np.asarray(self.max_integral), self.max_integral)
        rate = (e - self._previous) / dt if self._previous is not None and dt > 0 else 0.0
        self._previous = e.copy()
        return self.kp * e + self.ki * self.integral + self.kd * rate

    def reset(self) -> None:
        self.integral, self._previous = None, None
        self.output = np.zeros(0)

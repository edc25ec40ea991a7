"""Constraint Controllers (paper §4.1 "CC"): the control law that turns an output y and its
setpoint y_d into the desired output velocity for the velocity-resolved Solver, or into bounds on it.

Equality Task (:func:`equality_control`)::

    ydot_d = sat(ff + kp e + ki int(e) + kd de/dt),   saturated per component at max_output

Error convention (:func:`control_error`): ``e = y_d - y``, except for a complete rotation triple
(``rotation``: its first row in y, from the Constraint Output of a ``CartesianVKC`` in ``xyz_log3``
coordinates) where ``e = log3(R_d R^T)``, R = exp3(y[triple]): the rotation from the current to the
desired orientation, expressed in o1, matching the VKC's angular-velocity rows, so ``omega = kp e``
turns along the geodesic. A lone rotation component (e.g. ``['rz']``) uses the plain difference,
exact for rotations about that single axis (a mobile base's heading).

Inequality Task (:func:`inequality_control`, bounds ``lower``/``upper`` on y, e.g. distance >=
d_min): ``kp (lower - y) <= ydot <= kp (upper - y)``, so a violated bound is recovered at rate kp
and a satisfied one is approached no faster than exponentially.

The laws (:class:`ConstraintController`: :class:`PController`, :class:`PIDController`) keep their
gains as plain attributes (``kp``, ``ki``, ``kd``, ``max_output``; scalars or vectors) so a
Configurator can switch them between named configurations (e.g. ``high_accuracy_control``).
"""

from __future__ import annotations

import math
from typing import Protocol, TypeAlias

import numpy as np
import pinocchio as pin

__all__ = ['ConstraintController', 'PController', 'PIDController', 'Control', 'control_error', 'equality_control',
           'inequality_control']


#: Per output ``(desired, lower, upper, setpoint, error)``: the desired velocity, bounds on it (both
#: the desired velocity for an equality), the setpoint controlled to and the error, the fields of
#: ``itasc_msgs/Control`` (a plain tuple: built at every tick of every Task).
Control: TypeAlias = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]


class ConstraintController(Protocol):
    """A control law: the desired output velocity for an error and a feed-forward velocity."""

    kp: float | np.ndarray

    def __call__(self, error: np.ndarray, feedforward: np.ndarray | float, dt: float) -> np.ndarray: ...

    def reset(self) -> None:
        """Forget internal state (the Task was (re)activated)."""


def control_error(y: np.ndarray, y_desired: np.ndarray, *, rotation: int | None = None) -> np.ndarray:
    """``e = y_d - y``; on a complete rotation triple at row ``rotation``, ``log3(R_d R^T)``."""
    e = y_desired - y
    if rotation is not None:
        r = slice(rotation, rotation + 3)
        e[r] = pin.log3(pin.exp3(y_desired[r]) @ pin.exp3(y[r]).T)
    return e


def equality_control(controller: ConstraintController, y: np.ndarray, setpoint: np.ndarray,
                     feedforward: np.ndarray | float, dt: float, *, rotation: int | None = None) -> Control:
    """Track ``setpoint`` (with its feed-forward velocity): ``ydot = controller(e, ff, dt)``."""
    error = control_error(y, setpoint, rotation=rotation)
    desired = controller(error, feedforward, dt)
    return desired, desired, desired, setpoint, error


def inequality_control(y: np.ndarray, *, lower: np.ndarray | float, upper: np.ndarray | float,
                       kp: float | np.ndarray) -> Control:
    """Keep y within ``[lower, upper]``: ``kp (lower - y) <= ydot <= kp (upper - y)``. Inside the band
    the setpoint is y itself (no error); beyond it, the nearest bound. An infinite bound is no bound
    at any gain (with ``kp = 0`` it would be 0 * inf = NaN)."""
    setpoint = np.clip(y, lower, upper)
    if isinstance(kp, (int, float)) and kp > 0 or np.all(np.asarray(kp) > 0):
        low, high = kp * (lower - y), kp * (upper - y)
    else:
        low, high = _gained_bound(kp, lower, y), _gained_bound(kp, upper, y)
    return np.zeros(y.shape), low, high, setpoint, setpoint - y


def _gained_bound(kp: float | np.ndarray, bound: np.ndarray | float, y: np.ndarray) -> np.ndarray:
    """``kp (bound - y)`` where the bound is finite, the bound itself where it is infinite."""
    infinite = np.isinf(bound)
    return np.where(infinite, bound, kp * (np.where(infinite, 0.0, bound) - y))


def _saturate(out: np.ndarray, limit: float | np.ndarray) -> np.ndarray:
    """``out`` clipped to ``[-limit, limit]`` per component (an infinite float: no limit)."""
    if isinstance(limit, float) and math.isinf(limit):
        return out
    return np.minimum(np.maximum(out, -np.asarray(limit)), limit)


class PController:
    """Proportional control with feed-forward and output saturation."""

    def __init__(self, *, kp: float | np.ndarray = 1.0, max_output: float | np.ndarray = math.inf) -> None:
        self.kp = kp
        self.max_output = max_output

    def __call__(self, error: np.ndarray, feedforward: np.ndarray | float, dt: float) -> np.ndarray:
        """Desired output velocity: ``sat(ff + kp e)``."""
        return _saturate(feedforward + self.kp * error, self.max_output)

    def reset(self) -> None:
        """Nothing to forget."""


class PIDController:
    """PID with feed-forward, output saturation and anti-windup: the integral is clamped to
    ``max_integral`` and frozen on components whose output saturated; the derivative is the
    finite difference of the error (zero on the first call after ``reset``)."""

    def __init__(self, *, kp: float | np.ndarray = 1.0, ki: float | np.ndarray = 0.0,
                 kd: float | np.ndarray = 0.0, max_output: float | np.ndarray = math.inf,
                 max_integral: float | np.ndarray = math.inf) -> None:
        self.kp, self.ki, self.kd = kp, ki, kd
        self.max_output, self.max_integral = max_output, max_integral
        self.integral: np.ndarray | None = None
        self._previous: np.ndarray | None = None
        self._output = np.zeros(0)

    def __call__(self, error: np.ndarray, feedforward: np.ndarray | float, dt: float) -> np.ndarray:
        """Desired output velocity: ``sat(ff + kp e + ki int(e) + kd de/dt)``."""
        if self.integral is None or self.integral.shape != error.shape:
            self.integral = np.zeros_like(error)
        free = np.abs(self._output) < self.max_output if self._output.shape == error.shape else True
        self.integral = np.clip(self.integral + np.where(free, error * dt, 0.0),
                                -np.asarray(self.max_integral), self.max_integral)
        rate = (error - self._previous) / dt if self._previous is not None and dt > 0 else 0.0
        self._previous = error.copy()
        self._output = _saturate(feedforward + self.kp * error + self.ki * self.integral + self.kd * rate,
                                 self.max_output)
        return self._output

    def reset(self) -> None:
        self.integral, self._previous = None, None
        self._output = np.zeros(0)

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

The laws themselves (P, PID, ...) are the registered kinds of :mod:`itasc_tasks.controllers`.
"""

from __future__ import annotations

from typing import TypeAlias

import numpy as np
import pinocchio as pin

from .controllers import ConstraintController

__all__ = ['Control', 'control_error', 'equality_control', 'inequality_control']


#: Per output ``(desired, lower, upper, setpoint, error)``: the desired velocity, bounds on it (both
#: the desired velocity for an equality), the setpoint controlled to and the error, the fields of
#: ``itasc_msgs/Control`` (a plain tuple: built at every tick of every Task).
Control: TypeAlias = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def control_error(y: np.ndarray, y_desired: np.ndarray, *, rotation: int | None = None) -> np.ndarray:
    """``e = y_d - y``; on a complete rotation triple at row ``rotation``, ``log3(R_d R^T)``."""
    e = y_desired - y
    if rotation is not None:
        r = slice(rotation, rotation + 3)
        e[r] = pin.log3(pin.exp3(y_desired[r]).dot(pin.exp3(y[r]).T))
    return e


def equality_control(controller: ConstraintController, y: np.ndarray, setpoint: np.ndarray,
                     feedforward: np.ndarray | float, dt: float, *, rotation: int | None = None) -> Control:
    """Track ``setpoint`` (with its feed-forward velocity): ``ydot = controller(e, ff, dt)``."""
    error = control_error(y, setpoint, rotation=rotation)
    desired = controller(error, feedforward, dt)
    if not (isinstance(desired, np.ndarray) and desired.shape == error.shape):  # a plugin's law got it wrong
        got = f'{desired.size} values' if isinstance(desired, np.ndarray) else repr(desired)[:60]
        raise TypeError(f'constraint controller {type(controller).__name__} returned {got} for {error.size} '
                        f'outputs: expected an array of {error.size} values')
    return desired, desired, desired, setpoint, error


def inequality_control(y: np.ndarray, *, lower: np.ndarray | float, upper: np.ndarray | float,
                       kp: float | np.ndarray) -> Control:
    """Keep y within ``[lower, upper]``: ``kp (lower - y) <= ydot <= kp (upper - y)``. Inside the band
    the setpoint is y itself (no error); beyond it, the nearest bound. An infinite bound is no bound
    at any gain (with ``kp = 0`` it would be 0 * inf = NaN)."""
    setpoint = np.minimum(np.maximum(y, lower), upper)  # np.clip: the same through two Python wrappers
    if isinstance(kp, (int, float)) and kp > 0 or np.all(np.asarray(kp) > 0):
        low, high = kp * (lower - y), kp * (upper - y)
    else:
        low, high = _gained_bound(kp, lower, y), _gained_bound(kp, upper, y)
    return np.zeros(y.shape), low, high, setpoint, setpoint - y


def _gained_bound(kp: float | np.ndarray, bound: np.ndarray | float, y: np.ndarray) -> np.ndarray:
    """``kp (bound - y)`` where the bound is finite, the bound itself where it is infinite."""
    infinite = np.isinf(bound)
    return np.where(infinite, bound, kp * (np.where(infinite, 0.0, bound) - y))


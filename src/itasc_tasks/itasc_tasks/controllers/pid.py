"""The Constraint Controller ``pid``: PID with feed-forward, saturation and anti-windup."""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from .kind import ConstraintController, Gains, limits, saturate

__all__ = ['PIDController', 'PIDGains']


class PIDGains(Gains):
    """A PID's gains."""

    ki: float = Field(default=0.0, ge=0, allow_inf_nan=False)
    """Integral gain [1/s²] (finite)."""
    kd: float = Field(default=0.0, ge=0, allow_inf_nan=False)
    """Derivative gain (dimensionless, finite)."""
    max_integral: float = Field(default=math.inf, gt=0)
    """Bound of the integral of the error (anti-windup) [unit of the output · s]; ``.inf``: none."""


class PIDController(ConstraintController):
    """Proportional, integral, derivative: ``ydot_d = sat(ff + kp e + ki int(e) + kd de/dt)``. The
    integral is clamped to ``max_integral`` and frozen on components whose output saturated; the
    derivative is the finite difference of the error (zero on the first call after ``reset``)."""

    Parameters = PIDGains

    def __init__(self, *, kp: float | np.ndarray = 1.0, ki: float | np.ndarray = 0.0,
                 kd: float | np.ndarray = 0.0, max_output: float | np.ndarray = math.inf,
                 max_integral: float | np.ndarray = math.inf) -> None:
        self.kp, self.ki, self.kd = kp, ki, kd
        self.max_output, self.max_integral = max_output, max_integral
        self.integral: np.ndarray | None = None
        self._previous: np.ndarray | None = None
        self._output = np.zeros(0)

    def __call__(self, error: np.ndarray, feedforward: np.ndarray | float, dt: float) -> np.ndarray:
        integral = self.integral if self.integral is not None and self.integral.shape == error.shape \
            else np.zeros_like(error)
        step = error * dt
        if limits(self.max_output) and self._output.shape == error.shape:
            step[np.abs(self._output) >= self.max_output] = 0.0  # frozen where the output saturated
        integral = integral + step
        if limits(self.max_integral):
            integral = np.minimum(np.maximum(integral, -np.asarray(self.max_integral)), self.max_integral)
        self.integral = integral
        out = feedforward + self.kp * error
        if _acts(self.ki):
            out += self.ki * integral
        if _acts(self.kd) and self._previous is not None and dt > 0:
            out += self.kd * ((error - self._previous) / dt)
        self._previous = error.copy()
        self._output = saturate(out, self.max_output)
        return self._output

    def reset(self) -> None:
        self.integral, self._previous = None, None
        self._output = np.zeros(0)


def _acts(gain: float | np.ndarray) -> bool:
    """Whether a term with ``gain`` adds anything (a zero float adds nothing; a call per tick saved)."""
    return not (isinstance(gain, (int, float)) and gain == 0)

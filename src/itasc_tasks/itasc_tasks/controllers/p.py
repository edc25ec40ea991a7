"""The Constraint Controller ``p``: proportional control with feed-forward and saturation."""

from __future__ import annotations

import math

import numpy as np

from .kind import ConstraintController, saturate

__all__ = ['PController']


class PController(ConstraintController):
    """Proportional: ``ydot_d = sat(ff + kp e)``."""

    def __init__(self, *, kp: float | np.ndarray = 1.0, max_output: float | np.ndarray = math.inf) -> None:
        self.kp = kp
        self.max_output = max_output

    def __call__(self, error: np.ndarray, feedforward: np.ndarray | float, dt: float) -> np.ndarray:
        return saturate(feedforward + self.kp * error, self.max_output)

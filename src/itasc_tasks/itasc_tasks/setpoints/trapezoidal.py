"""The Setpoint Generator ``trapezoidal``: a point-to-point motion with bounded velocity and
acceleration."""

from __future__ import annotations

import math

from pydantic import Field, field_validator

from ..setpoint_generator import TrapezoidalSetpoint
from .kind import SetpointKind, Target, as_list, positive

__all__ = ['Trapezoidal']


class TrapezoidalMotion(Target):
    duration: float = Field(default=0.0, ge=0)
    """Shortest time to reach the target [s]."""
    max_velocity: list[float] | None = None
    """Largest speed per output [unit/s] (omitted: none)."""
    max_acceleration: list[float] | None = None
    """Largest acceleration per output [unit/s²] (omitted: 1)."""

    _list = field_validator('max_velocity', 'max_acceleration', mode='before')(as_list)
    _positive = field_validator('max_velocity', 'max_acceleration')(positive)


class Trapezoidal(SetpointKind):
    """From the current output to ``value``/``pose`` with a trapezoidal velocity profile within
    ``max_velocity`` and ``max_acceleration``, stretched to ``duration``."""

    Parameters = TrapezoidalMotion
    example = '{kind: trapezoidal, value: [0.3], max_velocity: 0.1, max_acceleration: 0.5}'

    @classmethod
    def generator(cls, params: TrapezoidalMotion) -> TrapezoidalSetpoint:
        return TrapezoidalSetpoint(params.target, duration=params.duration,
                                   max_velocity=params.max_velocity or math.inf,
                                   max_acceleration=params.max_acceleration or 1.0)

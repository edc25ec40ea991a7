"""The Setpoint Generator ``minimum_jerk``: a smooth point-to-point motion to a target."""

from __future__ import annotations

from pydantic import Field, field_validator

from ..setpoint_generator import MinimumJerkSetpoint
from .kind import SetpointKind, Target, as_list, positive

__all__ = ['MinimumJerk']


class MinimumJerkMotion(Target):
    duration: float = Field(default=0.0, ge=0)
    """Time to reach the target [s] (0: as fast as ``max_velocity`` allows, or at once)."""
    max_velocity: list[float] | None = None
    """Largest speed per output [unit/s] (a pose: linear, angular)."""

    _list = field_validator('max_velocity', mode='before')(as_list)
    _positive = field_validator('max_velocity')(positive)


class MinimumJerk(SetpointKind):
    """From the current output to ``value``/``pose`` along a minimum-jerk profile, in ``duration``
    and within ``max_velocity``; again from the current output whenever the Task is activated."""

    Parameters = MinimumJerkMotion

    @classmethod
    def generator(cls, params: MinimumJerkMotion) -> MinimumJerkSetpoint:
        return MinimumJerkSetpoint(params.target, duration=params.duration, max_velocity=params.max_velocity)

"""The Setpoint Generator ``fixed``: a constant target."""

from __future__ import annotations

from ..setpoint_generator import FixedSetpoint
from .kind import SetpointKind, Target

__all__ = ['Fixed']


class Fixed(SetpointKind):
    """A constant target, ``value`` or ``pose``."""

    Parameters = Target
    example = '{kind: fixed, value: [0.05]}'

    @classmethod
    def generator(cls, params: Target) -> FixedSetpoint:
        return FixedSetpoint(params.target)

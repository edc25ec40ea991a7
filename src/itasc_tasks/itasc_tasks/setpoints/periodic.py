"""The Setpoint Generator ``periodic``: ``offset + amplitude sin(2 pi t / period + phase)``."""

from __future__ import annotations

from pydantic import Field, field_validator

from itasc_core.computation.parameters import ParameterModel

from ..setpoint_generator import PeriodicSetpoint
from .kind import SetpointKind, as_list

__all__ = ['Periodic']


class Sine(ParameterModel):
    amplitude: list[float]
    """Per output (one value: all)."""
    period: float = Field(gt=0)
    """Period [s]."""
    offset: list[float] | None = None
    """Centre per output (omitted: 0)."""
    phase: list[float] | None = None
    """Phase per output [rad] (omitted: 0)."""

    _list = field_validator('amplitude', 'offset', 'phase', mode='before')(as_list)


class Periodic(SetpointKind):
    """A sine per output: ``offset + amplitude sin(2 pi t / period + phase)``."""

    Parameters = Sine
    example = '{kind: periodic, amplitude: [0.1], period: 4.0}'

    @classmethod
    def generator(cls, params: Sine) -> PeriodicSetpoint:
        return PeriodicSetpoint(amplitude=params.amplitude, period=params.period, offset=params.offset or 0.0,
                                phase=params.phase or 0.0)

"""The Monitor conditions the project ships: a value ``above`` or ``below`` a threshold, ``outside``
a band, ``stale`` data, ``nonfinite`` values."""

from __future__ import annotations

import math
from collections.abc import Sequence

from pydantic import Field, field_validator

from ..parameters import ParameterModel
from .kind import Condition

__all__ = ['Above', 'Below', 'Outside', 'Stale', 'NonFinite', 'Threshold', 'Band']


class Threshold(ParameterModel):
    threshold: float = 0.0
    """The threshold, in the watched value's unit."""


class Band(ParameterModel):
    band: tuple[float, float]
    """The band [low, high], in the watched value's unit."""

    @field_validator('band')
    @classmethod
    def _ordered(cls, value: tuple[float, float]) -> tuple[float, float]:
        if value[0] > value[1]:
            raise ValueError(f'low {value[0]} is above high {value[1]}')
        return value


class Above(Condition):
    """Any watched value is above ``threshold``."""

    Parameters = Threshold
    params: Threshold

    def holds(self, values: Sequence[float] | None, *, age: float, seen: bool = True) -> bool:
        return values is not None and any(v > self.params.threshold for v in values)


class Below(Condition):
    """Any watched value is below ``threshold``."""

    Parameters = Threshold
    params: Threshold

    def holds(self, values: Sequence[float] | None, *, age: float, seen: bool = True) -> bool:
        return values is not None and any(v < self.params.threshold for v in values)


class Outside(Condition):
    """Any watched value is outside ``band``."""

    Parameters = Band
    params: Band

    def holds(self, values: Sequence[float] | None, *, age: float, seen: bool = True) -> bool:
        low, high = self.params.band
        return values is not None and any(v < low or v > high for v in values)


class StaleParameters(ParameterModel):
    timeout: float = Field(default=0.5, gt=0)
    """The silence that makes the data stale [s]."""
    grace: float = Field(default=0.0, ge=0)
    """How long the first sample may take after the Monitor is switched on [s] (a driver coming up)."""


class Stale(Condition):
    """No new value arrived for ``timeout`` (the first one: for the longer of ``timeout`` and ``grace``)."""

    Parameters = StaleParameters
    params: StaleParameters
    example = '{name: setpoint_silent, watch: Approach.setpoint, condition: stale, timeout: 0.2, event: e_emergency}'
    reads_values = False

    def holds(self, values: Sequence[float] | None, *, age: float, seen: bool = True) -> bool:
        p = self.params
        return age > (p.timeout if seen else max(p.timeout, p.grace))


class NonFinite(Condition):
    """Any watched value is not finite (NaN, infinite)."""

    example = '{name: broken_output, watch: Approach.output, condition: nonfinite, event: e_emergency}'

    def holds(self, values: Sequence[float] | None, *, age: float, seen: bool = True) -> bool:
        return values is not None and any(not math.isfinite(v) for v in values)

"""The Monitor condition ``near``: every watched value is within ``tolerance`` of ``target``."""

from __future__ import annotations

from collections.abc import Sequence

from itasc_core.computation.conditions import Condition
from itasc_core.computation.parameters import ParameterModel
from pydantic import Field

__all__ = ['Near']


class NearParameters(ParameterModel):
    target: float = 0.0
    """The value to be near, in the watched value's unit."""
    tolerance: float = Field(default=0.01, gt=0)
    """How near, in the watched value's unit."""


class Near(Condition):
    """Every watched value is within ``tolerance`` of ``target``."""

    Parameters = NearParameters
    params: NearParameters

    def holds(self, values: Sequence[float] | None, *, age: float, seen: bool = True) -> bool:
        p = self.params
        return bool(values) and all(abs(v - p.target) <= p.tolerance for v in values)

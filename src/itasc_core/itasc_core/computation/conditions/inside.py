"""The Monitor condition ``inside``: every watched value is inside ``band``, the counterpart of
``outside`` (e.g. a Task's output arrived in a tolerance band around its target)."""

from __future__ import annotations

from collections.abc import Sequence

from .builtin import Band
from .kind import Condition

__all__ = ['Inside']


class Inside(Condition):
    """Every watched value is inside ``band`` (bounds included)."""

    Parameters = Band
    example = '{name: arrived, watch: Approach.error_norm, condition: inside, band: [0.0, 0.005], event: e_arrived}'
    params: Band

    def holds(self, values: Sequence[float] | None, *, age: float, seen: bool = True) -> bool:
        low, high = self.params.band
        return bool(values) and all(low <= v <= high for v in values)

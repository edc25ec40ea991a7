"""What a run's durations were, in memory that does not grow with the run (paper §6.2 the Timer:
the summary's tick-time and solve-time percentiles).

A run at 1 kHz ticks 3.6 million times an hour: keeping every tick time grows the bootstrap by
tens of MB an hour. :class:`Distribution` counts each value in a logarithmic bin instead, so any
percentile is known to within the bins' relative width (0.1 %), from a fixed ~180 kB.
"""

from __future__ import annotations

import math
from array import array
from bisect import bisect_left
from itertools import accumulate

__all__ = ['Distribution']


class Distribution:
    """Counts of positive values in logarithmic bins from ``low`` to ``high`` of relative width
    ``resolution``; the smallest and largest values are kept exactly."""

    def __init__(self, *, low: float = 1e-7, high: float = 1e3, resolution: float = 1e-3) -> None:
        self._low = low
        self._step = math.log1p(resolution)
        self._bins = array('q', bytes(8 * (math.ceil(math.log(high / low) / self._step) + 2)))
        self.count = 0
        self.minimum = math.inf
        self.maximum = -math.inf

    def add(self, value: float) -> None:
        """Count ``value``; a value that is not finite is no duration and is not counted."""
        if not math.isfinite(value):
            return
        index = 0 if value <= self._low else min(len(self._bins) - 1,
                                                 int(math.log(value / self._low) / self._step) + 1)
        self._bins[index] += 1
        self.count += 1
        self.minimum = min(self.minimum, value)
        self.maximum = max(self.maximum, value)

    def percentile(self, q: float) -> float | None:
        """The ``q``-th percentile, nearest rank, to within the resolution; None without values."""
        if not self.count:
            return None
        rank = min(self.count, max(1, math.ceil(q / 100 * self.count)))
        index = bisect_left(list(accumulate(self._bins)), rank)
        middle = self._low * math.exp((index - 0.5) * self._step) if index else self._low
        return min(self.maximum, max(self.minimum, middle))

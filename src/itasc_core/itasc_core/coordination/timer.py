"""The Timer (paper §6.2): triggers the root composite's Scheduler periodically.

It also measures what a user of a control loop wants to know: the achieved rate and how long a
tick takes from trigger to completion (the whole hierarchy's computations).
"""

from __future__ import annotations

import time
from collections import deque

from ..entity import CompositeContext, Entity
from .scheduler import Scheduler

__all__ = ['Timer']


class Timer(Entity):
    """Ticks ``scheduler`` at ``rate`` Hz with the time since the Timer started."""

    def __init__(self, *, composite: CompositeContext, scheduler: Scheduler, rate: float, window: int = 5000) -> None:
        super().__init__('timer', composite=composite)
        self.rate = rate
        self._scheduler = scheduler
        self._t0 = time.monotonic()
        self.durations: deque[float] = deque(maxlen=window)
        self.stamps: deque[float] = deque(maxlen=window)
        self._timer = self.create_timer(1.0 / rate, self._tick)

    def _tick(self) -> None:
        start = time.monotonic()
        self._scheduler.tick(start - self._t0)
        if self._scheduler.active:
            self.durations.append(time.monotonic() - start)
            self.stamps.append(start)

    def achieved_rate(self) -> float:
        if len(self.stamps) < 2:
            return 0.0
        span = self.stamps[-1] - self.stamps[0]
        return (len(self.stamps) - 1) / span if span > 0 else 0.0

    def destroy_node(self) -> None:
        self.destroy_timer(self._timer)
        super().destroy_node()

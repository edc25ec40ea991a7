"""The Timer (paper §6.2): triggers the root composite's Scheduler periodically, and after each
tick the Coordinators of the process (``after_tick``: the Composer's coordination), so that what
a tick raised is acted on before the next.

It also measures what a user of a control loop wants to know: the achieved rate and how long a
tick takes from trigger to completion (the whole hierarchy's computations and the coordination after them).

It keeps an absolute schedule, a tick due every period from its start, as a control loop that sleeps
until ``next_iteration_time += period`` does (ros2_control's): a tick that starts late, or one that
runs longer than a period, is followed at once by the one it delayed, instead of the missed period
being dropped as a ROS timer drops it, as long as the ticks gain on the schedule. A Timer behind by
more than ``catch_up`` periods (the process was stopped, the machine stalled) drops what it missed
instead, and counts it in ``dropped``: a burst of stale ticks would only command the robot from old
measurements.

Other threads of the process (the Runtime's worker building a re-composition's entities off the
tick path, the recorder's writer) hold the interpreter for up to Python's switch interval (5 ms by
default, half a period at 100 Hz) before a due tick gets it. While it runs, the Timer shortens that
interval to a twentieth of its period, at least 0.5 ms (measured with ``bench/bench_recompose.py``
at 100 Hz: ticks up to 2.9 periods apart while a step ran, 1.95 after). A ROS call holds the
interpreter longer, for the whole call: the worker makes its calls in the gap after a tick, which
the Timer announces (:mod:`..pace`).
"""

from __future__ import annotations

import sys
import time
from collections import deque
from typing import Callable

from rclpy.clock import Clock, ClockType

from ..entity import CompositeContext, Entity
from ..pace import PACE
from .scheduler import Scheduler

__all__ = ['Timer']


#: The share of a period another thread may hold the interpreter before a due tick gets it.
SWITCH_SHARE = 1 / 20
#: ... but no less than this (shorter intervals cost every thread more switches than they save).
MIN_SWITCH_INTERVAL = 0.0005
#: How many periods late a Timer may be and still run the ticks it missed (at 1 kHz on a 2-core
#: VM, the stalls of a shared machine reach 3-6 ms: with 2, 1.5 % of the ticks were dropped).
CATCH_UP = 5
#: The switch interval each running Timer of this process asks for, and the interpreter's before the
#: first. The interval is the process's: with several Timers (two applications in one process) the
#: shortest asked for holds, never longer than it was, until the last Timer is gone.
_asked: dict[int, float] = {}
_before: list[float] = []


def _ask_switch_interval(timer: int, interval: float | None) -> None:
    """Timer ``timer`` asks for ``interval`` (None: it is gone); set the process's accordingly."""
    if not _asked:
        _before[:] = [sys.getswitchinterval()]
    if interval is None:
        _asked.pop(timer, None)
    else:
        _asked[timer] = interval
    sys.setswitchinterval(min([_before[0], *_asked.values()]))


class Timer(Entity):
    """Ticks ``scheduler`` at ``rate`` Hz with the time since the Timer started."""

    def __init__(self, *, composite: CompositeContext, scheduler: Scheduler, rate: float, window: int = 5000,
                 after_tick: Callable[[], None] | None = None, catch_up: int = CATCH_UP) -> None:
        super().__init__('timer', composite=composite)
        self.rate = rate
        self._scheduler = scheduler
        #: Called after each tick, inside its measured time (the Composer's coordination between ticks).
        self._after_tick = after_tick
        self.catch_up = catch_up
        self.durations: deque[float] = deque(maxlen=window)
        self.stamps: deque[float] = deque(maxlen=window)
        #: Ticks run, and ticks dropped (due while the Timer was more than ``catch_up`` periods behind).
        self.ticked = 0
        self.dropped = 0
        #: ``time.monotonic()`` at program time 0: a tick that starts at ``m`` ticks ``t = m - origin``.
        self.origin = time.monotonic()
        # The steady clock, the one time.monotonic reads: the schedule is counted on it.
        self._timer = self.create_timer(1.0 / rate, self.run_due, clock=Clock(clock_type=ClockType.STEADY_TIME))
        _ask_switch_interval(id(self), max(MIN_SWITCH_INTERVAL, SWITCH_SHARE / rate))

    def _due(self) -> int:
        """How many ticks were due by now."""
        return int((time.monotonic() - self.origin) * self.rate)

    @property
    def next_due(self) -> float:
        """When the next tick is due (``time.monotonic()``)."""
        return self.origin + (self.ticked + 1) / self.rate

    def run_due(self) -> None:
        """Run the ticks due by now (the ROS timer's callback; a thread that spins between ticks
        calls it itself, see ``itasc_bringup.between_ticks``)."""
        before = None
        # Catching up while it gains on the schedule: a hierarchy whose ticks outlast the period
        # would never catch up, and must not keep the executor from its services and events.
        while (behind := self._due() - self.ticked) > 0 and (before is None or behind < before):
            if behind > self.catch_up + 1:
                if self._scheduler.active:  # not the stalls of a bring-up, when nothing computes
                    self.dropped += behind - 1
                self.ticked += behind - 1
                behind = 1
            self._tick()
            before = behind
        PACE.ticked(id(self), next_due=self.next_due, period=1.0 / self.rate)

    def _tick(self) -> None:
        self.ticked += 1
        start = time.monotonic()
        self._scheduler.tick(start - self.origin)
        if self._after_tick is not None:
            self._after_tick()
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
        _ask_switch_interval(id(self), None)
        PACE.gone(id(self))
        super().destroy_node()

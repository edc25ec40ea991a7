"""Pacing the ROS calls of the work that runs beside the ticks (paper §3.1: the Composer changes
the architecture of a running composite; a step must not delay the ticks of what keeps running).

rclpy holds the interpreter for the whole of each of its C calls, and creating or destroying a node
or one of its endpoints is a call of 0.5-2 ms (Fast DDS matches the endpoint with every local one of
the other side). A thread that builds a re-composition's entities off the tick path therefore
delays a due tick by the call it is in, whatever the switch interval. A thread that called
:meth:`Pace.pace_this_thread` makes each such call in the gap after a tick instead (the Timers of
the process tell when their next tick is due); every other thread calls at once.
"""

from __future__ import annotations

import threading
import time
from typing import Callable

__all__ = ['PACE', 'Pace']

#: The time a paced call wants before the next tick [s]: the longest endpoint creation measured
#: on a 2-core VM, with a margin. A fast Timer's gap is shorter: then half its period.
NEED = 0.002
#: A paced call waits for at most this many ticks of a Timer whose ticks leave no such gap, then
#: goes on (a hierarchy whose ticks fill their period would otherwise hold the work back for ever).
PATIENCE = 5


class Pace:
    """When the ticks of this process's Timers leave room for a paced call."""

    def __init__(self, *, clock: Callable[[], float] = time.monotonic) -> None:
        self._clock = clock
        self._changed = threading.Condition()
        #: Timer -> (when its next tick is due, its period), monotonic [s].
        self._due: dict[int, tuple[float, float]] = {}
        self._paced = threading.local()
        self._waiting = 0

    def ticked(self, timer: int, *, next_due: float, period: float) -> None:
        """Timer ``timer`` has ticked; its next tick is due at ``next_due``."""
        self._due[timer] = (next_due, period)
        if self._waiting:  # the tick path takes the lock only while a paced call waits
            with self._changed:
                self._changed.notify_all()

    def gone(self, timer: int) -> None:
        """Timer ``timer`` ticks no more."""
        with self._changed:
            self._due.pop(timer, None)
            self._changed.notify_all()

    def pace_this_thread(self) -> None:
        """The calling thread's ROS calls wait for a gap between ticks from now on (see :meth:`gap`)."""
        self._paced.on = True

    def gap(self) -> None:
        """In a paced thread: return once the next tick of the process is at least :data:`NEED` away
        (half its Timer's period, if shorter), after :data:`PATIENCE` ticks, or at once when that
        tick is more than a period overdue (its Timer stopped, or its executor is held: waiting for
        it would only hold the work back); elsewhere at once."""
        if not getattr(self._paced, 'on', False):
            return
        with self._changed:
            self._waiting += 1  # before reading when ticks are due: a tick from now on wakes this
            try:
                for _ in range(PATIENCE):
                    if not self._due:
                        return
                    next_due, period = min(self._due.values())
                    left = next_due - self._clock()
                    if left >= min(NEED, period / 2) or left < -period:
                        return
                    self._changed.wait(timeout=left + period)  # woken by the tick
            finally:
                self._waiting -= 1


#: The process's.
PACE = Pace()

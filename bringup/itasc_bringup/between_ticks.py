"""What the bootstrap's thread does between two ticks of the root Timer (issue #9): wait in the
executor until its next event (the Timer's ROS timer), or spin: run the Timer's due ticks itself
as soon as they are due, never sleeping shortly before one.

On a virtual machine a thread that sleeps between ticks finds the next tick much slower: the same
ticks of ``approach_object``, called in a loop in one process on the 2-core KVM guest, took a median
435 us back to back, 470 us with a busy wait of 0.4 ms between them and 591-633 us with a sleep or
an executor wait there (ten alternating rounds of 800 ticks). A sleep halts the vCPU, and the tick
after it runs on cold caches and branch predictors. rclpy's ``spin_once(timeout_sec=0)`` sleeps
too when nothing is waiting, for the thread's timer slack (the kernel's 50 us: ~70 us a call, a
voluntary context switch every time); a spinning thread sets its slack to 1 ns, and the call
returns after ~16 us without sleeping. It serves the executor whenever the next tick is more than
:data:`SERVE_BEFORE` away (one callback's time), and every :data:`SERVE_AT_LEAST` in any case,
before a due tick too: ticks that fill the period (a loaded machine) are run back to back, and a
loop that ran them first served nothing while they were behind; the joint states of a driver in
another process then went untaken until its Driver was taken for silent (Safety;
``approach_object_ros_driver`` at 1 kHz with ``--between-ticks spin``, two runs of two). The whole
application at 1 kHz, ``--deploy single``, two alternating pairs of 20 s runs
(``bench/bench_app.py --json --between-ticks wait|auto``): tick p50 758/811 -> 531/648 us, p99
1141/1198 -> 1026/1053 us, 991/981 -> 998/998 Hz, 187/379 -> 46/39 ticks dropped.

Spinning keeps a core busy. So ``auto`` (the default) spins only at :data:`SPIN_RATE` Hz and more
(the ~0.2 ms a sleep costs a tick matters in a period of a few milliseconds, not in one of 10 ms)
once the ticks take :data:`SPIN_FROM` of the period while it waits (the median of the recent ones):
the third of a tick a sleep costs is then a tenth of the period or more. Spinning, the ticks are
shorter, so the share it sees then is turned into the share they would take waiting, by how much
shorter they became when it started to spin (:data:`MAX_SLOWDOWN` at most), and it waits again once
that is below :data:`WAIT_BELOW`. Thresholds on the share as it comes were a trap (50 % to spin, 30 %
to wait again): ``approach_object`` at 1 kHz takes 35-37 % of the period spinning and 40-57 % waiting
(15 s runs, ``bench/bench_app.py --json --between-ticks spin|wait``), so it waited for good, its
ticks 1.1-1.5x longer, when its first ticks took less than half the period or a quiet moment took
the spinning ones below 30 %. ``spin`` and ``wait`` choose for good.

A spinning thread only wins while the core it holds has nothing else to do: ``auto`` does not spin
while composites of the application run in other processes of this machine (``alone()`` false,
``--deploy per-composite``), whose ticks need every core. ``approach_object`` per composite at
500 Hz on the 2-core VM (five processes, 0.08 of a core idle) began to spin in 3 of 10 runs (its
ticks grew to 30 % of the period under load); told to spin, two pairs of 20 s runs: the Solver
stepped at 425/417 Hz against 439/462 Hz waiting, and the rows of its Tasks were too old to be
combined (the robot held still) 8/5 times against 2/1. The machine's idle time would say the same
of any other load, but it is no guide while an application starts (its display process takes ~2 s
of CPU): a threshold on it (a quarter of a core) kept ``--deploy single --record`` at 1 kHz from
spinning through its first seconds, 971-994 Hz against 995-998 Hz in four pairs.
"""

from __future__ import annotations

import ctypes
import itertools
import statistics
import sys
import time
from typing import TYPE_CHECKING, Any, Callable

if TYPE_CHECKING:
    from itasc_core.composition.realtime import ThreadPriority

__all__ = ['BetweenTicks', 'MAX_SLOWDOWN', 'MODES', 'SPIN_FROM', 'SPIN_RATE', 'WAIT_BELOW']

MODES = ('auto', 'spin', 'wait')
#: ``auto`` spins at this rate [Hz] and more ...
SPIN_RATE = 250.0
#: ... once the ticks take this share of the period while it waits between them ...
SPIN_FROM = 0.3
#: ... and waits again once they would take less than this waiting (see :data:`MAX_SLOWDOWN`).
WAIT_BELOW = 0.2
#: Spinning, the share the ticks would take waiting is the spinning share times how much longer the
#: ticks took before it started to spin than after (the median of each), at least 1, at most this.
MAX_SLOWDOWN = 2.0
#: How long the executor waits for an event while the thread does not spin [s].
WAIT = 0.02
#: Spinning, the executor is served while the next tick is further away than this [s] ...
SERVE_BEFORE = 0.00015
#: ... and at least this often in any case [s].
SERVE_AT_LEAST = 0.002
#: The timer slack of a spinning thread [ns] (``prctl(PR_SET_TIMERSLACK)``).
SPINNING_SLACK = 1
#: The share is the median of the newest ``RECENT // 2`` ticks, once ``RECENT`` ran (the first
#: ticks of a run are slow), and of at least ``RECENT // 4`` when only those since a moment count;
#: ``auto`` looks at it every ``DECIDE_PERIOD`` seconds.
RECENT = 200
DECIDE_PERIOD = 0.25
#: Ticks older than this [s] do not count: a Timer whose hierarchy stopped computing is idle.
STALE = 0.5


class BetweenTicks:
    """Between the ticks of the root Timer ``timer()`` (None before there is one)."""

    def __init__(self, mode: str = 'auto', *, timer: Callable[[], Any],
                 on_change: Callable[[bool, float], None] | None = None,
                 clock: Callable[[], float] = time.monotonic, alone: Callable[[], bool] = lambda: True,
                 priority: ThreadPriority | None = None) -> None:
        """``on_change(spinning, share)``: told when ``auto`` starts or stops spinning; ``alone()``:
        whether no composite of the application computes in another process of this machine;
        ``priority``: the real-time priority of the thread while the hierarchy computes in the
        Timer's ticks and it waits (:mod:`itasc_core.composition.realtime`; never while it spins)."""
        if mode not in MODES:
            raise ValueError(f'between ticks: {mode!r} is not one of {MODES}')
        self.mode = mode
        self._timer = timer
        self._priority = priority
        self._alone = alone
        self._on_change = on_change
        self._clock = clock
        self.spinning = mode == 'spin'
        self._decided_at = -float('inf')
        self._served_at = -float('inf')
        #: ``auto``, spinning: when it started, the share before, and the slowdown once measured.
        self._spun_at = -float('inf')
        self._waiting_share = 0.0
        self._slowdown: float | None = None
        #: Spinning: the timer slack the thread had before [ns].
        self._slack: int | None = None

    def step(self, executor) -> None:
        """One turn of the thread: the executor's next event (waiting for it at most
        :data:`WAIT`), or, spinning, the due ticks, the executor served, or nothing."""
        timer = self._timer()
        if timer is None or not self._spin():
            if self._priority is not None:
                self._priority.realtime(timer is not None and self._computing(timer))
            if self._slack is not None:
                _timer_slack(self._slack)
                self._slack = None
            executor.spin_once(timeout_sec=WAIT)
            return
        if self._priority is not None:
            self._priority.realtime(False)
        if self._slack is None:
            self._slack = _timer_slack(SPINNING_SLACK)
        now = self._clock()
        left = timer.next_due - now
        if left > SERVE_BEFORE or now - self._served_at >= SERVE_AT_LEAST:
            self._served_at = now
            executor.spin_once(timeout_sec=0.0)
        elif left <= 0.0:
            timer.run_due()

    def _computing(self, timer: Any) -> bool:
        """Whether the hierarchy computes in the Timer's ticks (a Timer ticks through the bring-up
        with nothing to compute)."""
        return bool(timer.stamps) and self._clock() - timer.stamps[-1] <= max(STALE, 2.0 / timer.rate)

    def _spin(self) -> bool:
        if self.mode != 'auto' or self._clock() - self._decided_at < DECIDE_PERIOD:
            return self.spinning
        self._decided_at = self._clock()
        share = self.share()
        alone = self._alone()
        if not self.spinning:
            if share >= SPIN_FROM and alone:
                self._spun_at, self._waiting_share, self._slowdown = self._clock(), share, None
                self._change(True, share)
        elif not share or not alone:  # stale, or no longer fast: nothing to spin for; or its core is needed
            self._change(False, share)
        else:
            if self._slowdown is None:
                spinning_share = self.share(since=self._spun_at)
                if not spinning_share:  # too few ticks since it started to spin
                    return True
                self._slowdown = min(MAX_SLOWDOWN, max(1.0, self._waiting_share / spinning_share))
            if share * self._slowdown < WAIT_BELOW:
                self._change(False, share)
        return self.spinning

    def _change(self, spinning: bool, share: float) -> None:
        self.spinning = spinning
        if self._on_change is not None:
            self._on_change(spinning, share)

    def share(self, *, since: float = -float('inf')) -> float:
        """The median share of the period the newest computing ticks took (those that started after
        ``since``, ``time.monotonic()``); 0 before there are enough, and below :data:`SPIN_RATE`."""
        timer = self._timer()
        if timer is None or timer.rate < SPIN_RATE or len(timer.stamps) < RECENT or not self._computing(timer):
            return 0.0
        newest = list(itertools.islice(
            itertools.takewhile(lambda tick: tick[0] > since, zip(reversed(timer.stamps), reversed(timer.durations))),
            RECENT // 2))
        if len(newest) < RECENT // 4:
            return 0.0
        return statistics.median(duration for _, duration in newest) * timer.rate


_PR_SET_TIMERSLACK, _PR_GET_TIMERSLACK = 29, 30


def _timer_slack(nanoseconds: int) -> int:
    """Set the calling thread's timer slack (Linux; elsewhere nothing); returns the one it had."""
    if not sys.platform.startswith('linux'):
        return 0
    prctl = ctypes.CDLL(None).prctl
    old = prctl(_PR_GET_TIMERSLACK, 0, 0, 0, 0)
    prctl(_PR_SET_TIMERSLACK, nanoseconds, 0, 0, 0)
    return old

"""Real-time scheduling of the threads that tick (issue #9; paper §6.1, the Timer's tick).

With ``--deploy per-composite`` a tick travels through several processes (the bootstrap's Timer,
the program's process, each Task's), each of whose main threads waits for its trigger. On a
loaded machine the kernel wakes such a thread late: the root's Timer then ran missed ticks back to
back (a quarter of the program process's triggers came within 1 ms of the one before at 500 Hz on
a 2-core VM) and the program's process stepped the Solver at 425-441 Hz of 500. Like ros2_control's
controller_manager (its ``thread_priority``, 50 by default), these threads ask for ``SCHED_FIFO``
while the application runs: woken at once, they run ahead of the display, the recorder's writer and
DDS's own threads, and give the core back as soon as they wait again. Two pairs of 20 s runs: the
Solver at 482 / 468 Hz with it, 425 / 441 Hz without (the root 498 / 494 against 487 / 491 Hz).

A thread that spins between ticks (``--between-ticks``) keeps the normal policy: a real-time thread
that never sleeps is throttled by the kernel (``sched_rt_runtime_us``, 0.95 s of every second;
949-952 instead of 993-999 Hz at 1 kHz). Where the policy is not permitted (an unprivileged user
whose ``ulimit -r`` is 0: see the README) the thread ticks at the normal one, and says so once.
"""

from __future__ import annotations

import os
from typing import Callable

__all__ = ['DEFAULT_PRIORITY', 'ENV', 'ThreadPriority', 'priority_from_env']

#: The real-time priority of a ticking thread (1-99; ros2_control's default).
DEFAULT_PRIORITY = 50
#: How the bootstrap hands ``--thread-priority`` to the composite processes it starts.
ENV = 'ITASC_THREAD_PRIORITY'


def priority_from_env() -> int:
    """The priority the bootstrap asked for (:data:`ENV`), :data:`DEFAULT_PRIORITY` if none or
    none of 0-99 (a composite process started by a host agent has the agent's environment)."""
    value = os.environ.get(ENV, '').strip()
    return int(value) if value.isdigit() and int(value) <= 99 else DEFAULT_PRIORITY


class ThreadPriority:
    """Puts the calling thread under ``SCHED_FIFO`` at ``priority`` while asked to
    (:meth:`realtime`), and back under the normal policy; ``priority`` 0: never. ``refused(why)``
    is told once if the policy is not permitted."""

    def __init__(self, priority: int = DEFAULT_PRIORITY, *, refused: Callable[[str], None] = lambda why: None) -> None:
        if not 0 <= priority <= 99:
            raise ValueError(f'a thread priority is 0 (normal scheduling) or 1-99, not {priority}')
        self.priority = priority
        self._refused = refused
        self._failed = False
        #: Whether the thread runs under SCHED_FIFO now.
        self.on = False

    def realtime(self, on: bool) -> None:
        """Run the calling thread under ``SCHED_FIFO`` (``on``) or the normal policy."""
        on = on and self.priority > 0 and not self._failed
        if on == self.on:
            return
        try:
            policy, param = (os.SCHED_FIFO, self.priority) if on else (os.SCHED_OTHER, 0)
            os.sched_setscheduler(0, policy, os.sched_param(param))
        except (OSError, AttributeError) as err:  # not permitted; AttributeError: not Linux
            self._failed = True
            self._refused(f'real-time priority {self.priority} not permitted ({err}; ulimit -r is '
                          f'{_rtprio_limit()}): ticking at normal priority')
            return
        self.on = on


def _rtprio_limit() -> str:
    try:
        import resource
        soft, _ = resource.getrlimit(resource.RLIMIT_RTPRIO)
    except (ImportError, AttributeError, OSError):
        return 'unknown'
    return 'unlimited' if soft == resource.RLIM_INFINITY else str(soft)

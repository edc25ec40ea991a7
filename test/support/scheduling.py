"""Whether this test process may put a thread under SCHED_FIFO (root, or a ``ulimit -r`` above 0):
the tests of the real-time priority of the ticking threads skip where it may not."""

from __future__ import annotations

import os

import pytest

__all__ = ['fifo_permitted', 'needs_fifo']


def fifo_permitted() -> bool:
    policy = os.sched_getscheduler(0)
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))
    except PermissionError:
        return False
    os.sched_setscheduler(0, policy, os.sched_param(0))
    return True


#: Marks a test that needs SCHED_FIFO.
needs_fifo = pytest.mark.skipif(not fifo_permitted(), reason='SCHED_FIFO is not permitted here (ulimit -r is 0)')

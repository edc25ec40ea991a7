"""Whether this test process may put a thread under SCHED_FIFO (root, or a ``ulimit -r`` above 0):
the tests of the real-time priority of the ticking threads skip where it may not."""

from __future__ import annotations

import pytest

from itasc_core.composition.realtime import ThreadPriority

__all__ = ['fifo_permitted', 'needs_fifo']


def fifo_permitted() -> bool:
    probe = ThreadPriority(1)
    probe.realtime(True)
    permitted = probe.on
    probe.realtime(False)
    return permitted


#: Marks a test that needs SCHED_FIFO.
needs_fifo = pytest.mark.skipif(not fifo_permitted(), reason='SCHED_FIFO is not permitted here (ulimit -r is 0)')

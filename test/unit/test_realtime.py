"""The real-time priority of the threads that tick (itasc_core.composition.realtime): ``SCHED_FIFO``
at the priority asked for while the application runs, the normal policy otherwise, and one line
saying why where the policy is not permitted."""

from __future__ import annotations

import os
import subprocess
import sys
import threading

import pytest
from scheduling import needs_fifo

from itasc_core.composition.realtime import DEFAULT_PRIORITY, ENV, ThreadPriority, priority_from_env


def _in_a_thread(run):
    """What ``run()`` returns, called in a thread of its own (the policy is the calling thread's)."""
    result = []
    thread = threading.Thread(target=lambda: result.append(run()))
    thread.start()
    thread.join()
    return result[0]


@needs_fifo
def test_the_calling_thread_runs_under_sched_fifo_while_asked_and_the_normal_policy_after():
    def run():
        priority = ThreadPriority(50)
        priority.realtime(True)
        during = os.sched_getscheduler(0), os.sched_getparam(0).sched_priority, priority.on
        priority.realtime(False)
        return during, (os.sched_getscheduler(0), priority.on)

    assert _in_a_thread(run) == ((os.SCHED_FIFO, 50, True), (os.SCHED_OTHER, False))
    assert os.sched_getscheduler(0) == os.SCHED_OTHER  # the other threads keep theirs


def test_priority_0_leaves_the_thread_at_the_normal_policy():
    def run():
        priority = ThreadPriority(0)
        priority.realtime(True)
        return os.sched_getscheduler(0), priority.on

    assert _in_a_thread(run) == (os.SCHED_OTHER, False)
    with pytest.raises(ValueError, match='0 .normal scheduling. or 1-99, not 100'):
        ThreadPriority(100)


def test_where_the_policy_is_not_permitted_it_says_why_once_and_ticks_at_the_normal_one():
    """An unprivileged user whose ``ulimit -r`` is 0 (here: root turned into nobody, which drops
    the capability, with the limit at 0)."""
    code = ('import os, resource\n'
            'from itasc_core.composition.realtime import ThreadPriority\n'
            'if os.geteuid() == 0:\n'
            '    os.setuid(65534)\n'
            'resource.setrlimit(resource.RLIMIT_RTPRIO, (0, 0))\n'
            'said = []\n'
            'priority = ThreadPriority(50, refused=said.append)\n'
            'for _ in range(3):\n'
            '    priority.realtime(True)\n'
            'print(len(said), said[0], os.sched_getscheduler(0) == os.SCHED_OTHER, priority.on)\n')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, check=True,
                         env=dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))).stdout
    assert out.strip() == ('1 real-time priority 50 not permitted ([Errno 1] Operation not permitted; ulimit -r '
                           'is 0): ticking at normal priority True False')


@pytest.mark.parametrize('value, priority', [('0', 0), ('80', 80), ('', DEFAULT_PRIORITY), ('150', DEFAULT_PRIORITY),
                                             ('high', DEFAULT_PRIORITY)])
def test_a_composite_process_takes_the_priority_its_bootstrap_asked_for_or_the_default(monkeypatch, value, priority):
    monkeypatch.setenv(ENV, value)
    assert priority_from_env() == priority

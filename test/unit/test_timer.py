"""The Timer's hold on the interpreter's switch interval (:mod:`itasc_core.coordination.timer`): it is
the process's, so with two Timers in one process (two applications, as in a test process) the
shorter interval holds until the last Timer is gone, then the interpreter's own comes back."""

from __future__ import annotations

import sys

import pytest
import rclpy
from rclpy.signals import SignalHandlerOptions

from itasc_core.coordination.scheduler import Scheduler
from itasc_core.coordination.timer import Timer
from itasc_core.entity import CompositeContext


@pytest.fixture
def timer():
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    schedulers: list[Scheduler] = []

    def make(name: str, rate: float) -> Timer:
        context = CompositeContext(name=name, namespace=f'/timer_test/{name}')
        schedulers.append(Scheduler(composite=context))
        return Timer(composite=context, scheduler=schedulers[-1], rate=rate)
    before = sys.getswitchinterval()
    yield make
    for scheduler in schedulers:
        scheduler.destroy_node()
    sys.setswitchinterval(before)
    rclpy.try_shutdown()


def test_the_shortest_interval_holds_until_the_last_timer_is_gone(timer):
    before = sys.getswitchinterval()
    first = timer('first', 100.0)
    assert sys.getswitchinterval() == pytest.approx(0.0005)  # a twentieth of 10 ms
    second = timer('second', 20.0)
    assert sys.getswitchinterval() == pytest.approx(0.0005)
    first.destroy_node()
    assert sys.getswitchinterval() == pytest.approx(min(before, 1 / 20 / 20))  # the 20 Hz Timer's: 2.5 ms
    second.destroy_node()
    assert sys.getswitchinterval() == pytest.approx(before)

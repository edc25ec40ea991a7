"""The pace of the work beside the ticks (itasc_core.pace): a paced thread's ROS call waits for the
gap after a tick, and never for ever. Plain Python: the clock is the test's."""

import threading
import time

from itasc_core.pace import NEED, PATIENCE, Pace

#: Long, so that no wait of a paced call times out (after a period) while a test runs.
PERIOD = 1.0


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def call_in_a_paced_thread(pace: Pace) -> tuple[threading.Thread, threading.Event]:
    """A thread that makes one paced call; the event is set once the call may go."""
    went = threading.Event()

    def work() -> None:
        pace.pace_this_thread()
        pace.gap()
        went.set()

    thread = threading.Thread(target=work, daemon=True)
    thread.start()
    return thread, went


def test_a_call_waits_while_a_tick_is_near_and_goes_in_the_gap_after_it():
    clock = Clock()
    pace = Pace(clock=clock)
    pace.ticked(1, next_due=clock.now + NEED / 4, period=PERIOD)
    thread, went = call_in_a_paced_thread(pace)
    assert not went.wait(timeout=0.2), 'a call went though a tick was due in a quarter of what it needs'
    clock.now += NEED  # the tick ran
    pace.ticked(1, next_due=clock.now + 2 * NEED, period=PERIOD)
    assert went.wait(timeout=2.0), 'the call did not go in the gap after the tick'
    thread.join()


def test_a_call_goes_at_once_when_the_next_tick_is_far_or_nothing_ticks_or_the_thread_is_not_paced():
    clock = Clock()
    pace = Pace(clock=clock)
    assert call_in_a_paced_thread(pace)[1].wait(timeout=2.0), 'no Timer: the call must go'
    pace.ticked(1, next_due=clock.now + 2 * NEED, period=0.01)
    assert call_in_a_paced_thread(pace)[1].wait(timeout=2.0), 'the next tick is far: the call must go'
    pace.ticked(1, next_due=clock.now, period=0.01)
    start = time.monotonic()
    pace.gap()  # this thread is not paced (the executor's thread must never wait for its own ticks)
    assert time.monotonic() - start < 0.05


def test_a_fast_timer_lets_a_call_go_with_half_its_period_left():
    clock = Clock()
    pace = Pace(clock=clock)
    period = NEED  # shorter than NEED would leave no gap at all
    pace.ticked(1, next_due=clock.now + 0.6 * period, period=period)
    assert call_in_a_paced_thread(pace)[1].wait(timeout=2.0)


def test_ticks_that_leave_no_gap_hold_a_call_back_a_few_ticks_only():
    clock = Clock()
    pace = Pace(clock=clock)
    pace.ticked(1, next_due=clock.now, period=PERIOD)
    thread, went = call_in_a_paced_thread(pace)
    for _ in range(PATIENCE - 1):
        assert not went.wait(timeout=0.05)
        pace.ticked(1, next_due=clock.now, period=PERIOD)  # overrunning ticks: always due
    assert not went.wait(timeout=0.05)
    pace.ticked(1, next_due=clock.now, period=PERIOD)
    assert went.wait(timeout=2.0), f'a call waited for more than {PATIENCE} ticks'
    thread.join()


def test_a_timer_that_stopped_ticking_holds_no_call_back():
    clock = Clock()
    pace = Pace(clock=clock)
    pace.ticked(1, next_due=clock.now - 1.5 * PERIOD, period=PERIOD)  # its process is stopping
    assert call_in_a_paced_thread(pace)[1].wait(timeout=0.2), 'a call waited for a Timer that no longer ticks'


def test_a_timer_that_ends_lets_the_waiting_call_go():
    clock = Clock()
    pace = Pace(clock=clock)
    pace.ticked(1, next_due=clock.now, period=PERIOD)
    thread, went = call_in_a_paced_thread(pace)
    assert not went.wait(timeout=0.05)
    pace.gone(1)
    assert went.wait(timeout=2.0)
    thread.join()

"""What the bootstrap's thread does between ticks (itasc_bringup.between_ticks): ``auto`` spins at
250 Hz and more once the ticks take 30 % of the period while it waits, and waits again once they
would take less than 20 % waiting (the spinning share times the slowdown it measured when it began
to spin), and never while composites of the application compute in other processes of the
machine; spinning, it runs the Timer's due ticks itself and serves the executor while the next
tick is far, and every 2 ms in any case, ticks behind or not, with no sleep in an idle call."""

import ctypes
import os
import resource
from collections import deque

import pytest

from itasc_bringup.between_ticks import (MAX_SLOWDOWN, RECENT, SERVE_AT_LEAST, SERVE_BEFORE, STALE, WAIT, WAIT_BELOW,
                                         BetweenTicks)


@pytest.fixture(autouse=True)
def _timer_slack_kept():
    """A spinning BetweenTicks sets this thread's timer slack: each test leaves it as it found it."""
    prctl = ctypes.CDLL(None).prctl
    slack = prctl(30, 0, 0, 0, 0)  # PR_GET_TIMERSLACK
    yield
    prctl(29, slack, 0, 0, 0)  # PR_SET_TIMERSLACK


class _Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


class _Timer:
    """What the policy uses of the root Timer: its rate, newest ticks, next due tick, run_due()."""

    def __init__(self, clock: _Clock, rate: float = 1000.0) -> None:
        self.rate, self._clock = rate, clock
        self.stamps: deque[float] = deque(maxlen=5000)
        self.durations: deque[float] = deque(maxlen=5000)
        self.next_due = clock.now + 1.0 / rate
        self.ran = 0

    def ran_for(self, count: int, *, share: float) -> None:
        """``count`` ticks, each ``share`` of the period, the last one just now."""
        self._clock.now += 1.0
        for k in range(count):
            self.stamps.append(self._clock.now - (count - k) / self.rate)
            self.durations.append(share / self.rate)
        self.next_due = self._clock.now + 1.0 / self.rate

    def run_due(self) -> None:
        self.ran += 1
        self.next_due += 1.0 / self.rate


class _Executor:
    """What the policy uses of the executor: how long each ``spin_once`` could wait."""

    def __init__(self) -> None:
        self.waits: list[float] = []

    def spin_once(self, *, timeout_sec: float) -> None:
        self.waits.append(timeout_sec)


@pytest.fixture
def auto():
    clock = _Clock()
    timer, executor, changes = _Timer(clock), _Executor(), []
    between = BetweenTicks('auto', timer=lambda: timer, clock=clock,
                           on_change=lambda spinning, share: changes.append((spinning, round(share, 2))))
    return between, timer, executor, clock, changes


def test_auto_spins_once_waiting_ticks_take_30_percent_and_waits_when_they_would_take_under_20(auto):
    between, timer, executor, clock, changes = auto
    between.step(executor)
    assert executor.waits == [WAIT] and not between.spinning  # no tick yet
    timer.ran_for(RECENT // 2, share=0.9)
    between.step(executor)
    assert not between.spinning  # too few ticks to tell: the first ones are slow
    timer.ran_for(RECENT, share=0.25)
    between.step(executor)
    assert not between.spinning
    timer.ran_for(RECENT, share=0.4)
    between.step(executor)
    assert between.spinning and changes == [(True, 0.4)]
    timer.ran_for(RECENT, share=0.25)  # spinning, they are shorter: waiting they took 1.6x as long
    between.step(executor)
    assert between.spinning
    timer.ran_for(RECENT, share=0.15)  # would take 24 % waiting
    between.step(executor)
    assert between.spinning
    timer.ran_for(RECENT, share=0.1)  # would take 16 % waiting
    between.step(executor)
    assert not between.spinning and changes == [(True, 0.4), (False, 0.1)]
    timer.ran_for(RECENT, share=0.25)
    between.step(executor)
    assert not between.spinning and executor.waits[-1] == WAIT


def test_auto_at_1_khz_is_not_trapped_waiting_by_ticks_that_a_wait_makes_slower(auto):
    """approach_object at 1 kHz (2-core VM): 40-57 % of the period waiting, 35-37 % spinning; with
    thresholds on the share as it came (spin from 50 %, wait below 30 %) it waited for good."""
    between, timer, executor, clock, changes = auto
    timer.ran_for(RECENT, share=0.45)
    between.step(executor)
    assert between.spinning
    timer.ran_for(RECENT, share=0.35)
    between.step(executor)
    timer.ran_for(RECENT, share=0.27)  # a quiet moment
    between.step(executor)
    assert between.spinning and changes == [(True, 0.45)]


def test_auto_counts_the_slowdown_on_ticks_since_it_began_to_spin_and_at_most_twofold(auto):
    between, timer, executor, clock, changes = auto
    timer.ran_for(RECENT, share=0.9)  # the slow first ticks of a run
    between.step(executor)
    assert between.spinning
    timer.ran_for(RECENT // 8, share=0.01)  # too few since it began to spin to measure anything
    between.step(executor)
    assert between.spinning
    timer.ran_for(RECENT, share=0.15)  # 6x shorter: counted as MAX_SLOWDOWN
    between.step(executor)
    assert between.spinning
    timer.ran_for(RECENT, share=0.95 * WAIT_BELOW / MAX_SLOWDOWN)
    between.step(executor)
    assert not between.spinning


def test_auto_waits_below_250_hz_however_long_the_ticks(auto):
    _, _, executor, clock, changes = auto
    timer = _Timer(clock, rate=100.0)  # a 10 ms period: ~0.2 ms a tick do not decide the rate
    between = BetweenTicks('auto', timer=lambda: timer, clock=clock)
    timer.ran_for(RECENT, share=0.9)
    between.step(executor)
    assert not between.spinning and executor.waits == [WAIT]


def test_auto_waits_once_the_timer_stopped_computing(auto):
    between, timer, executor, clock, changes = auto
    timer.ran_for(RECENT, share=0.8)
    between.step(executor)
    assert between.spinning
    clock.now += STALE + 0.5  # Safety, or stopped: no computing tick since
    between.step(executor)
    assert not between.spinning and changes[-1] == (False, 0.0) and executor.waits[-1] == WAIT


def test_auto_does_not_spin_while_composites_compute_in_other_processes_of_the_machine():
    """``--deploy per-composite``: a spinning thread would take the core their ticks need."""
    clock, executor, others = _Clock(), _Executor(), [1]
    timer = _Timer(clock)
    between = BetweenTicks('auto', timer=lambda: timer, clock=clock, alone=lambda: not others)
    timer.ran_for(RECENT, share=0.6)
    between.step(executor)
    assert not between.spinning and executor.waits == [WAIT]
    others.clear()  # they ended (a re-composition, a stop): alone again
    timer.ran_for(RECENT, share=0.6)
    between.step(executor)
    assert between.spinning
    others.append(1)
    timer.ran_for(RECENT, share=0.6)
    between.step(executor)
    assert not between.spinning and executor.waits[-1] == WAIT


def test_spinning_runs_due_ticks_at_once_and_serves_the_executor_only_far_from_the_next_tick():
    clock = _Clock()
    timer, executor = _Timer(clock), _Executor()
    between = BetweenTicks('spin', timer=lambda: timer, clock=clock)
    timer.next_due = clock.now + 0.0008  # far: the executor is served, without waiting
    between.step(executor)
    assert executor.waits == [0.0] and timer.ran == 0
    clock.now = timer.next_due - SERVE_BEFORE / 2  # close: nothing but the clock
    for _ in range(100):
        between.step(executor)
    assert executor.waits == [0.0] and timer.ran == 0
    clock.now = timer.next_due  # due: run by the spinning thread itself
    between.step(executor)
    assert timer.ran == 1 and executor.waits == [0.0]


def test_spinning_serves_the_executor_at_least_every_2_ms_even_when_ticks_fill_the_period():
    clock = _Clock()
    timer, executor = _Timer(clock), _Executor()
    between = BetweenTicks('spin', timer=lambda: timer, clock=clock)
    served = 0
    for _ in range(1000):  # 10 ms of ticks that leave less than SERVE_BEFORE before the next one
        clock.now += 0.00001
        timer.next_due = clock.now + SERVE_BEFORE / 2
        between.step(executor)
        served = len(executor.waits)
    assert served >= int(0.01 / SERVE_AT_LEAST) and all(wait == 0.0 for wait in executor.waits)


def test_spinning_serves_the_executor_every_2_ms_while_the_ticks_are_behind_and_run_back_to_back():
    clock = _Clock()
    timer, executor = _Timer(clock), _Executor()
    between = BetweenTicks('spin', timer=lambda: timer, clock=clock)
    timer.next_due = clock.now - 1.0  # far behind: a tick is due at every step
    for _ in range(1000):  # 0.1 s of steps
        clock.now += 0.0001
        between.step(executor)
    assert timer.ran > 900 and len(executor.waits) >= int(0.1 / SERVE_AT_LEAST)


def test_a_spinning_thread_serving_an_idle_executor_never_sleeps_and_waiting_again_sleeps_as_before():
    """rclpy's ``spin_once(timeout_sec=0)`` with nothing to do sleeps for the thread's timer slack
    (50 us by default); a spinning thread sets its slack to 1 ns, and a waiting one back."""
    import rclpy
    from itasc_core.composition.deployment import make_executor
    from rclpy.context import Context

    context = Context()
    rclpy.init(context=context, domain_id=int(os.environ.get('ROS_DOMAIN_ID', '0')))
    node = rclpy.create_node('between_ticks_test', context=context)
    executor = make_executor(context)
    executor.add_node(node)
    clock = _Clock()
    timer = _Timer(clock)
    between = BetweenTicks('auto', timer=lambda: timer, clock=clock)

    def sleeps(serve) -> int:
        """Voluntary context switches of this thread while ``serve()`` serves the idle executor 500 times."""
        before = resource.getrusage(resource.RUSAGE_THREAD).ru_nvcsw
        for _ in range(500):
            serve()
        return resource.getrusage(resource.RUSAGE_THREAD).ru_nvcsw - before

    def idle_call() -> None:
        executor.spin_once(timeout_sec=0.0)

    try:
        assert sleeps(idle_call) > 400  # the kernel's slack
        timer.ran_for(RECENT, share=0.6)
        timer.next_due = clock.now + 1.0  # the next tick far: every step serves the executor
        assert sleeps(lambda: between.step(executor)) == 0 and between.spinning
        timer.ran_for(RECENT, share=0.05)
        between.step(executor)  # waits again (one executor wait of WAIT)
        assert not between.spinning and sleeps(idle_call) > 400
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)


class _Priority:
    """What the policy uses of a ThreadPriority: whether the thread is to run at it now."""

    def __init__(self) -> None:
        self.on = False

    def realtime(self, on: bool) -> None:
        self.on = on


def test_the_thread_waits_at_its_real_time_priority_while_the_hierarchy_computes_and_never_spins_at_it():
    """Not through the bring-up (its work is no tick), nor once the ticks stopped computing; and a
    real-time thread that never sleeps is throttled by the kernel: it spins at the normal policy."""
    clock = _Clock()
    timer, executor, priority, deployed = _Timer(clock), _Executor(), _Priority(), []
    between = BetweenTicks('auto', timer=lambda: timer if deployed else None, clock=clock, priority=priority)
    between.step(executor)
    assert not priority.on  # the bring-up: no Timer yet
    deployed.append(True)
    between.step(executor)
    assert not priority.on  # a Timer, ticking with nothing to compute yet
    timer.ran_for(RECENT // 2, share=0.05)
    between.step(executor)
    assert priority.on and not between.spinning
    timer.ran_for(RECENT, share=0.6)
    between.step(executor)
    assert between.spinning and not priority.on
    timer.ran_for(RECENT, share=0.05)
    between.step(executor)
    assert not between.spinning and priority.on
    clock.now += 2 * STALE  # the hierarchy stopped computing (its stop, the teardown)
    between.step(executor)
    assert not priority.on


@pytest.mark.parametrize('mode, spinning', [('spin', True), ('wait', False)])
def test_spin_and_wait_hold_whatever_the_ticks_take(mode, spinning):
    clock = _Clock()
    timer, executor = _Timer(clock), _Executor()
    between = BetweenTicks(mode, timer=lambda: timer, clock=clock)
    for share in (0.05, 0.95):
        timer.ran_for(RECENT, share=share)
        between.step(executor)
        assert between.spinning == spinning


def test_an_unknown_mode_is_refused():
    with pytest.raises(ValueError, match="'sometimes' is not one of"):
        BetweenTicks('sometimes', timer=lambda: None)

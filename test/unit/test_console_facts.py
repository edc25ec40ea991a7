"""The console's run facts (bringup/itasc_bringup/console/facts.py, distribution.py): the figures the
summary reports, from memory that does not grow with the length of the run."""

from __future__ import annotations

import math
import tracemalloc
from types import SimpleNamespace

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from itasc_bringup.console.distribution import Distribution
from itasc_bringup.console.facts import SETTLING_BAND, RunFacts, Settling, TaskSpec


def settling_by_definition(t, values, band=SETTLING_BAND):
    """Seconds from t[0] until values stay within band of their peak (None: not yet; 0: never left)."""
    if not values:
        return None
    outside = [i for i, v in enumerate(values) if v > band * max(values)]
    if not outside:
        return 0.0
    return None if outside[-1] == len(values) - 1 else t[outside[-1] + 1] - t[0]


@settings(max_examples=300, deadline=None)
@given(st.lists(st.one_of(st.floats(0, 10), st.sampled_from([0.0, 1.0, 0.02, 0.0200001])), max_size=60))
def test_the_settling_time_per_tick_is_the_settling_time_of_the_whole_run(values):
    t = [0.5 + 0.01 * i for i in range(len(values))]
    settling = Settling()
    for stamp, value in zip(t, values):
        settling.add(stamp, value)
    expected = settling_by_definition(t, values)
    if expected is None:
        assert settling.after is None
    else:
        assert settling.after is not None and math.isclose(settling.after, expected, abs_tol=1e-12)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(1e-6, 1.0), min_size=1, max_size=500), st.sampled_from([1, 50, 90, 99, 100]))
def test_a_percentile_is_the_nearest_rank_to_within_a_thousandth(values, q):
    distribution = Distribution()
    for value in values:
        distribution.add(value)
    ordered = sorted(values)
    exact = ordered[min(len(ordered) - 1, max(0, math.ceil(q / 100 * len(ordered)) - 1))]
    assert distribution.count == len(values)
    assert math.isclose(distribution.percentile(q), exact, rel_tol=1e-3)


def test_durations_that_are_not_finite_are_not_counted():
    distribution = Distribution()
    assert distribution.percentile(50) is None
    for value in (0.001, math.nan, math.inf, 0.003):
        distribution.add(value)
    assert distribution.count == 2 and distribution.percentile(100) == 0.003


def _tick(facts: RunFacts, k: int) -> None:
    t = 1e-3 * k
    error = 0.5 * math.exp(-t) + 1e-4 * math.sin(k)
    facts.on_task('Approach', SimpleNamespace(t=t, error_norm=error, output=np.array([error])))
    facts.on_task('Avoid', SimpleNamespace(t=t, error_norm=0.0, output=np.array([0.2 + 0.05 * math.sin(t)])))
    facts.on_solver(SimpleNamespace(t=t, status='optimal', solve_time=1e-4 * (1 + (k % 7))))
    facts.on_ticks([t], [2e-4 * (1 + (k % 5))])


def test_a_long_run_does_not_grow_the_facts_and_keeps_its_figures():
    """An hour at 1 kHz is 3.6 million ticks: the facts must not keep them all."""
    facts = RunFacts(composites={'app': '/app'},
                     tasks=[TaskSpec('Approach', '/a'), TaskSpec('Avoid', '/b', inequality=True, lower=0.15)])
    for k in range(5000):
        _tick(facts, k)
    tracemalloc.start()
    before = tracemalloc.get_traced_memory()[0]
    for k in range(5000, 105_000):
        _tick(facts, k)
    grown = tracemalloc.get_traced_memory()[0] - before
    tracemalloc.stop()
    assert grown < 20_000, f'{grown} bytes more after 100,000 more ticks'
    approach, avoid = facts.tasks['Approach'], facts.tasks['Avoid']
    assert approach.ticks == avoid.ticks == facts.ticks.count == 105_000
    assert 0.4 < approach.peak_error < 0.6 and approach.final_error < 1e-3
    assert 3.0 < approach.converged_after < 5.0  # e^-t below 2 % of 0.5 after ln(50) ~ 3.9 s
    assert math.isclose(avoid.min_margin, 0.2 - 0.05 - 0.15, abs_tol=1e-6) and len(avoid.recent_distance) == 2000
    assert math.isclose(facts.tick_percentile(50), 6e-4, rel_tol=1e-3)
    assert math.isclose(facts.solve_percentile(100), 7e-4, rel_tol=1e-3)
    assert math.isclose(facts.achieved_rate(), 1000.0, rel_tol=1e-6)


def test_the_tick_figures_are_those_of_the_ticks_from_running_to_the_stop():
    """The bring-up and the stop of a large program hold the ticking thread for 0.1-0.3 s at a
    time (50 Tasks at 100 Hz: 92 ticks dropped in an 8 s run, none once Running): the summary's
    rate, tick times and dropped ticks are those of the run between the root's Running and the stop."""
    facts = RunFacts(composites={'app': '/app'}, tasks=[])
    stamps: list[float] = []
    durations: list[float] = []

    def ticks(first: float, count: int, *, period: float, duration: float) -> None:
        for k in range(count):
            stamps.append(first + k * period)
            durations.append(duration)

    ticks(0.0, 10, period=0.1, duration=0.05)  # the bring-up: late, long ticks
    facts.on_ticks(stamps, durations, dropped=5)
    ticks(1.001, 100, period=0.001, duration=0.0002)  # Running, seen before the console knew
    facts.on_ticks(stamps, durations, dropped=5)
    facts.count_ticks(since=1.0, dropped=5)
    ticks(1.101, 900, period=0.001, duration=0.0002)
    facts.on_ticks(stamps, durations, dropped=5)
    facts.count_ticks(until=2.0, dropped=5)
    ticks(2.1, 20, period=0.1, duration=0.08)  # the stop
    facts.on_ticks(stamps, durations, dropped=40)
    assert facts.ticks.count == 1000 and facts.dropped_ticks == 0
    assert math.isclose(facts.achieved_rate(), 1000.0, rel_tol=1e-6)
    assert math.isclose(facts.tick_percentile(100), 2e-4, rel_tol=1e-9)


def test_the_solver_rate_is_that_of_its_steps_from_running_to_the_stop():
    """With ``--deploy per-composite`` the Solver steps in a process of its own, triggered over DDS:
    its rate is that of its steps stamped (program time) between the root's Running and the stop,
    however late they arrive; the steps of the bring-up and of the stop do not count, and steps a
    busy process never made show. It was the steps of the whole run over the time in Running
    (a run whose Solver missed nothing read 495 Hz at 500 Hz)."""
    facts = RunFacts(composites={'app': '/app'}, tasks=[])
    origin = 100.0  # the root Timer's monotonic time at program time 0

    def step(t: float, topic: str = '/app/itasc/Solver/status') -> None:
        facts.on_solver(SimpleNamespace(t=t, status='ok', solve_time=2e-4), topic=topic)

    for k in range(500):  # the bring-up: the program runs before the root is seen Running
        step(k * 0.002)
    facts.count_ticks(since=origin + 1.0, dropped=0, origin=origin)
    assert facts.solver_rate() is None
    for k in range(500, 3000):
        if k % 50 != 0:  # its process misses one trigger in fifty
            step(k * 0.002)
    facts.count_ticks(until=origin + 6.0, dropped=0, origin=origin)
    for k in range(3000, 3100):  # the stop; and two late steps of the window, which count
        step(k * 0.002)
    step(5.9969), step(5.9989)
    assert math.isclose(facts.solver_rate(), 490.0, rel_tol=2e-3), facts.solver_rate()
    assert facts.solve_times.count == 500 + 2500 - 50 + 100 + 2  # every step's solve time counts, in the window or not


def test_of_several_solvers_the_rate_is_the_slowest():
    facts = RunFacts(composites={'app': '/app'}, tasks=[])
    facts.count_ticks(since=0.0, dropped=0, origin=0.0)
    for k in range(1000):
        facts.on_solver(SimpleNamespace(t=k * 0.002, status='ok', solve_time=1e-4), topic='/a/Solver/status')
        if k % 2:
            facts.on_solver(SimpleNamespace(t=k * 0.002, status='ok', solve_time=1e-4), topic='/b/Solver/status')
    assert math.isclose(facts.solver_rate(), 250.0, rel_tol=3e-3)

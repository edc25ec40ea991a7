"""The summary's lines (bringup/itasc_bringup/console/summary.py): what a person reads first."""

from __future__ import annotations

import math
from types import SimpleNamespace

from itasc_bringup.console.facts import RunFacts
from itasc_bringup.console.summary import build_summary, summary_lines


def rate_line(*, solver_every: int) -> str:
    """The rate line of a 500 Hz run whose Solver missed one tick in ``solver_every`` (0: none)."""
    facts = RunFacts(composites={'app': '/app'}, tasks=[])
    facts.count_ticks(since=0.0, dropped=0, origin=0.0)
    stamps = [k * 0.002 for k in range(1, 2001)]
    facts.on_ticks(stamps, [2e-4] * len(stamps))
    for k, t in enumerate(stamps):
        if not solver_every or k % solver_every:
            facts.on_solver(SimpleNamespace(t=t, status='ok', solve_time=1e-4), topic='/app/itasc/Solver/status')
    summary = build_summary(facts, app='app', how='duration', exit_code=0, safety=None, running_for=4.0,
                            up_after=1.0, target_rate=500.0, recording=None, trace=None, warnings=[])
    assert math.isfinite(summary['rate']['solver_hz'])
    return next(line for line in summary_lines(summary) if line.strip().startswith('rate'))


def test_the_rate_line_names_the_solver_rate_only_when_the_solver_missed_ticks():
    assert 'Solver stepped' not in rate_line(solver_every=0)
    assert 'Solver stepped' not in rate_line(solver_every=200)  # 0.5 % missed: within 99 %
    assert rate_line(solver_every=20).endswith('the Solver stepped at 475.2 Hz'), rate_line(solver_every=20)

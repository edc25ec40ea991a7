"""The summary at the end of every run (paper §6.1: how the life-cycle ended; §4.1: what each
Task achieved): the first thing a person reads, and, with ``--summary-json FILE``, what a script
or CI reads.

It says how the run ended and with which exit code, the Running sub-FSM path with its times,
per Task its final error and time to converge (equality) or its final distance and minimum
margin to its bounds (inequality), the achieved rate with the tick time's p50 and p99, the
recording with the command that plots it, and where the full trace is.
"""

from __future__ import annotations

import json
import math
import pathlib
from typing import Any

from .facts import RunFacts

__all__ = ['build_summary', 'summary_lines', 'write_summary_json']

#: The rate line names the Solver's own rate when it stepped less often than this share of the
#: ticks (``--deploy per-composite``: its process missed triggers).
SLOWER = 0.99


def _finite(value: float | None) -> float | None:
    return value if value is not None and math.isfinite(value) else None


def build_summary(facts: RunFacts, *, app: str, how: str, exit_code: int, safety: str | None,
                  running_for: float | None, up_after: float | None, target_rate: float, recording: str | None,
                  trace: str | None, warnings: list[str], process_up_after: float | None = None) -> dict[str, Any]:
    """The summary as plain data (what ``--summary-json`` writes). ``up_after``: seconds from the
    start of the bring-up to Running; ``process_up_after``: from the start of the process (its
    imports and the model's validation too)."""
    tasks = []
    for name, trace_ in facts.tasks.items():
        entry: dict[str, Any] = {'task': name, 'kind': 'inequality' if trace_.spec.inequality else 'equality',
                                 'ticks': trace_.ticks, 'final_error': _finite(trace_.final_error)}
        if trace_.spec.inequality:
            entry.update(d_min=_finite(trace_.spec.lower), d_max=_finite(trace_.spec.upper),
                         final_distance=_finite(trace_.final_distance), min_margin=_finite(trace_.min_margin))
        else:
            entry['converged_after'] = trace_.converged_after
        tasks.append(entry)
    p50, p99 = facts.tick_percentile(50), facts.tick_percentile(99)
    return {
        'app': app,
        'ended': how,
        'exit_code': exit_code,
        'safety': safety,
        'running_for': running_for,
        'up_after': up_after,
        'process_up_after': process_up_after,
        'paths': {composite: [{'state': state, 'at': at} for state, at in path]
                  for composite, path in facts.paths().items()},  # parents first
        'tasks': tasks,
        'rate': {'target': target_rate, 'achieved': facts.achieved_rate(),
                 'tick_p50': p50, 'tick_p99': p99, 'ticks': facts.ticks.count, 'dropped': facts.dropped_ticks,
                 'solve_p50': facts.solve_percentile(50), 'solves': facts.solve_times.count,
                 'solver_hz': facts.solver_rate()},
        'solver_status': facts.solver_status or None,
        'recording': recording,
        'plot_command': f'ros2 run itasc_bringup itasc-plot {recording}' if recording else None,
        'trace': trace,
        'warnings': warnings,
    }


def _num(value: float | None, unit: str = '') -> str:
    return '-' if value is None else f'{value:.4g}{unit}'


def _ms(value: float | None) -> str:
    return '-' if value is None else f'{value * 1e3:.2f} ms'


def summary_lines(summary: dict[str, Any]) -> list[str]:
    """The summary as lines, the verdict last (where a person looks first when a run ends)."""
    lines = ['--- summary ---']
    for i, (composite, path) in enumerate(summary['paths'].items()):
        steps = ' -> '.join(f'{step["state"]} {step["at"]:.2f} s' for step in path)
        lines.append(f'  {"path" if i == 0 else "":<6} {composite}: {steps}')
    width = max((len(t['task']) for t in summary['tasks']), default=0)
    for i, task in enumerate(summary['tasks']):
        if task['kind'] == 'inequality':
            bounds = ', '.join(f'{k} {task[k]:.4g}' for k in ('d_min', 'd_max') if task[k] is not None)
            what = (f'distance {_num(task["final_distance"], " m")} ({bounds}), '
                    f'min margin {_num(task["min_margin"], " m")}')
        else:
            after = task['converged_after']
            converged = 'not converged' if after is None else f'converged after {after:.2f} s'
            what = f'final error {_num(task["final_error"])}, {converged}' if task['ticks'] else 'never active'
        lines.append(f'  {"tasks" if i == 0 else "":<6} {task["task"]:<{width}}  {what}')
    rate = summary['rate']
    solver_hz = rate.get('solver_hz')
    lines.append(f'  {"rate":<6} {rate["achieved"]:.1f} Hz (target {rate["target"]:g}), '
                 f'tick p50 {_ms(rate["tick_p50"])}, p99 {_ms(rate["tick_p99"])}, solver p50 {_ms(rate["solve_p50"])}'
                 + (f', {rate["dropped"]} ticks dropped (the Timer was too far behind)' if rate['dropped'] else '')
                 + (f', the Solver stepped at {solver_hz:.1f} Hz' if solver_hz and solver_hz < SLOWER * rate['achieved']
                    else ''))
    if summary['up_after'] is not None:
        process = summary.get('process_up_after')
        lines.append(f'  {"up":<6} Running {summary["up_after"]:.2f} s after the bring-up began'
                     + (f' ({process:.2f} s after the process started)' if process is not None else ''))
    if summary['recording']:
        lines.append(f'  {"record":<6} {summary["recording"]}  (plot it: {summary["plot_command"]})')
    if summary['trace']:
        lines.append(f'  {"trace":<6} {summary["trace"]}')
    if summary['safety']:
        lines.append(f'  {summary["safety"]}')
    ran = f', {summary["running_for"]:.1f} s in Running' if summary['running_for'] is not None else ''
    lines.append(f'{summary["app"]}: stopped ({summary["ended"]}) - exit {summary["exit_code"]}{ran}')
    return lines


def write_summary_json(summary: dict[str, Any], path: pathlib.Path) -> None:
    path.write_text(json.dumps(summary, indent=2, allow_nan=False) + '\n')

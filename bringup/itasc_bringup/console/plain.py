"""The console without a terminal (piped, CI, ``ros2 launch``): plain lines (paper §6.1 life-cycle).

By default only what a user needs: the root's entry into each phase (Configure, Start, Running,
Stop, stopped), every Running sub-FSM transition of any composite, Safety, and at the end the
summary. ``--verbose`` prints every composite's every transition, as
``[state] <composite>: <state>  <- <event>``, and a ``[status]`` line (rate, task errors) at most
once a second when it changed. The full trace goes to the trace file either way.
"""

from __future__ import annotations

import sys
import time
from typing import Callable, TextIO

from ..outcome import RunOutcome
from .facts import RUNNING, RunFacts, Transition
from .trace import TraceFile

__all__ = ['PlainConsole', 'state_line', 'worth_showing', 'task_figure']


def state_line(tr: Transition) -> str:
    return f'[state] {tr.composite}: {tr.state}  <- {tr.event or "start"}'


def _phase(state: str) -> str:
    parts = state.split('.')
    return parts[1] if parts[0] == 'Active' and len(parts) > 1 else parts[0]


def worth_showing(tr: Transition, *, root: str, previous: str) -> bool:
    """Whether a user needs this transition: Safety, a Running sub-FSM transition, or the root
    entering a phase, Running, or its final state."""
    if tr.state == 'Safety' or RunFacts.sub_state(tr.state) is not None:
        return True
    if tr.composite != root:
        return False
    phase = _phase(tr.state)
    return tr.state == RUNNING or tr.state.endswith('NotifyStopped') or (phase != _phase(previous) and phase != 'Run')


def task_figure(facts: RunFacts, name: str) -> str:
    """A Task's latest figure in words: its error, or its distance against its bounds."""
    trace = facts.tasks[name]
    if trace.spec.inequality:
        if trace.final_distance is None:
            return 'distance -'
        return f'distance {trace.final_distance:.4f} m, margin {trace.margin(trace.final_distance):.4f} m'
    return f'error {trace.final_error:.4f}' if trace.final_error is not None else 'error -'


class PlainConsole:
    """Plain lines on ``stream``; every transition also into ``trace``."""

    def __init__(self, *, facts: RunFacts, outcome: RunOutcome, root: str, trace: TraceFile,
                 rate: Callable[[], float], verbose: bool = False, stream: TextIO = sys.stdout) -> None:
        self._facts, self._outcome, self._root, self._trace = facts, outcome, root, trace
        self._rate, self._verbose, self._stream = rate, verbose, stream
        self._previous: dict[str, str] = {}
        self._last_status, self._last_status_at = '', 0.0

    def _print(self, line: str) -> None:
        self._stream.write(line + '\n')
        self._stream.flush()

    def on_transition(self, tr: Transition) -> None:
        line = state_line(tr)
        self._trace.write(line)
        previous = self._previous.get(tr.composite, '')
        self._previous[tr.composite] = tr.state
        if self._verbose or worth_showing(tr, root=self._root, previous=previous):
            self._print(line)

    def show_safety(self) -> None:
        """Say once, on one line starting with ``SAFETY:``, why the run went to Safety."""
        line = self._outcome.new_safety_line()
        if line is not None:
            self.show(line)

    def show(self, line: str) -> None:
        """A line of its own (a notice such as :mod:`.waiting`'s), also into the trace."""
        self._trace.write(line)
        self._print(line)

    def refresh(self) -> None:
        """With ``--verbose``: a ``[status]`` line at most once a second, when it changed."""
        if not self._verbose:
            return
        rate = self._outcome.rate_text(self._rate())
        status = ' | '.join([f'rate {rate}'] + [f'{name} {task_figure(self._facts, name)}'
                                                  for name in self._facts.tasks])
        now = time.monotonic()
        if status != self._last_status and now - self._last_status_at >= 1.0:
            self._print(f'[status] {status}')
            self._last_status, self._last_status_at = status, now

    def close(self) -> None:
        """Nothing to restore: plain lines leave the stream as it was."""

    def finish(self, lines: list[str]) -> None:
        for line in lines:
            self._trace.write(line)
            self._print(line)

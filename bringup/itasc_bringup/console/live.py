"""The console on a terminal: one compact view, redrawn in place with ``rich`` (paper §6.1 the
composites' states and the Running sub-FSM; §4.1 each Task's error or distance; §6.2 the Timer).

It shows the composite tree with each composite's state, each Running sub-FSM's state and path
so far, per Task its error (equality) or its distance against its bounds (inequality) with a
small bar, the achieved rate and tick time, and the elapsed time against ``--duration``. A Safety
shows at once, in red, with its reason, also as a ``SAFETY:`` line above the view.
"""

from __future__ import annotations

import sys
import time
from typing import Any, Callable, TextIO

from rich.console import Console, Group
from rich.live import Live
from rich.progress_bar import ProgressBar
from rich.table import Table
from rich.text import Text
from rich.tree import Tree

from ..outcome import RunOutcome
from .facts import RunFacts, Transition
from .plain import state_line, task_figure
from .trace import TraceFile

__all__ = ['LiveConsole']

PHASE_STYLES = {'Configure': 'cyan', 'Start': 'green', 'Run': 'bold green', 'Stop': 'yellow', 'Safety': 'bold red'}


def _short(state: str) -> str:
    return state.removeprefix('Active.')


def _style(state: str) -> str:
    short = _short(state)
    return PHASE_STYLES.get(short.split('.')[0], '')


class LiveConsole:
    """A ``rich.live.Live`` view of ``facts``, refreshed by :meth:`refresh` from the main loop."""

    def __init__(self, *, facts: RunFacts, outcome: RunOutcome, root: str, trace: TraceFile,
                 rate: Callable[[], float], target_rate: float, elapsed: Callable[[], float | None],
                 duration: float | None, verbose: bool = False, stream: TextIO = sys.stdout,
                 period: float = 0.25) -> None:
        self._facts, self._outcome, self._root, self._trace = facts, outcome, root, trace
        self._rate, self._target, self._elapsed, self._duration = rate, target_rate, elapsed, duration
        self._verbose, self._period = verbose, period
        self._drawn_at = 0.0
        self.console = Console(file=stream)
        self._live = Live(console=self.console, auto_refresh=False, transient=False,
                          get_renderable=self.render)
        self._live.start()

    # -- events -------------------------------------------------------------------------------

    def on_transition(self, tr: Transition) -> None:
        line = state_line(tr)
        self._trace.write(line)
        if self._verbose:
            self.console.print(line, markup=False, highlight=False)

    def show_safety(self) -> None:
        line = self._outcome.new_safety_line()
        if line is not None:
            self.show(line, style='bold red')

    def show(self, line: str, *, style: str = '') -> None:
        """A line of its own above the view (a notice such as :mod:`.waiting`'s), also into the trace."""
        self._trace.write(line)
        self.console.print(Text(line, style=style))
        self._live.refresh()

    def refresh(self) -> None:
        now = time.monotonic()
        if now - self._drawn_at >= self._period:
            self._drawn_at = now
            self._live.refresh()

    def close(self) -> None:
        """Leave the terminal as it was (cursor shown), also when the run ended in an error."""
        if self._live.is_started:
            self._live.stop()

    def finish(self, lines: list[str]) -> None:
        self._live.refresh()
        self.close()
        for line in lines:
            self._trace.write(line)
        self.console.print(Text('\n'.join(lines)), highlight=False)

    # -- the view -----------------------------------------------------------------------------

    def render(self) -> Group:
        parts: list[Any] = [self._header(), self._tree()]
        if self._facts.tasks:
            parts.append(self._tasks())
        parts.append(self._timing())
        if self._outcome.went_through_safety:
            parts.append(Text(self._outcome.safety_line(), style='bold white on red'))
        return Group(*parts)

    def _header(self) -> Table:
        elapsed = self._elapsed()
        grid = Table.grid(padding=(0, 1))
        if elapsed is None:
            grid.add_row(Text('bringing up the hierarchy ...', style='dim'))
        elif self._duration:
            grid.add_row(Text('Running', style='bold'),
                         ProgressBar(total=self._duration, completed=min(elapsed, self._duration), width=30),
                         Text(f'{min(elapsed, self._duration):5.1f} / {self._duration:g} s'))
        else:
            grid.add_row(Text('Running', style='bold'), Text(f'{elapsed:5.1f} s (Ctrl-C stops)'))
        return grid

    def _tree(self) -> Tree:
        nodes: dict[str, Tree] = {}
        paths = self._facts.paths()
        tree = None
        for name, namespace in self._facts.composites.items():
            state = self._facts.states[name]
            label = Text.assemble((f'{name:<16}', 'bold'), ' ', (_short(state), _style(state)))
            if name in paths:
                label.append('   path: ' + ' → '.join(step for step, _ in paths[name]), style='magenta')
            parent = nodes.get(namespace.rsplit('/', 1)[0])
            nodes[namespace] = parent.add(label) if parent is not None else Tree(label, guide_style='dim')
            tree = tree or nodes[namespace]
        return tree or Tree('-')

    def _tasks(self) -> Table:
        table = Table(box=None, padding=(0, 1), show_header=True, header_style='dim')
        table.add_column('task', style='bold')
        table.add_column('now')
        table.add_column('', width=20)
        for name, trace in self._facts.tasks.items():
            bar: ProgressBar | Text
            if trace.spec.inequality and trace.final_distance is not None:
                margin = trace.margin(trace.final_distance)
                widest = max(trace.margin(d) for d in trace.recent_distance) or 1.0
                bar = ProgressBar(total=max(widest, 1e-9), completed=max(margin, 0.0), width=20,
                                  complete_style='red' if margin <= 0 else 'yellow')
            elif trace.final_error is not None:
                bar = ProgressBar(total=trace.peak_error or 1.0, completed=trace.final_error, width=20)
            else:
                bar = Text('inactive', style='dim')
            table.add_row(name, task_figure(self._facts, name), bar)
        return table

    def _timing(self) -> Text:
        recent = sorted(self._facts.recent_ticks)  # live: the latest ticks only (the summary: all)
        ticks = (f'tick p50 {recent[len(recent) // 2] * 1e3:.2f} ms, p99 '
                 f'{recent[min(len(recent) - 1, int(0.99 * len(recent)))] * 1e3:.2f} ms') if recent else 'no ticks yet'
        solver = f', solver {self._facts.solver_status}' if self._facts.solver_status else ''
        rate = self._outcome.rate_text(self._rate())
        return Text(f'rate {rate} (target {self._target:g}), {ticks}{solver}', style='dim')

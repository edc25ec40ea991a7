"""The bootstrap's live status: the state of every composite, the achieved rate, each task's error.

Refreshes in place on a terminal; writes plain lines (only when something changed, at most once a
second) when the output is not a TTY, e.g. under CI or when piped to a file. Once a composite is
in Safety nothing runs any more: the rate line gives way to the reason, in red on a terminal.
"""

from __future__ import annotations

import sys
import time
from typing import Callable, TextIO

from rclpy.node import Node

from itasc_core.communication.qos import DATA_QOS, STATE_QOS
from itasc_msgs.msg import CoordinatorState, TaskState

from .outcome import RunOutcome

__all__ = ['StatusDisplay']


class StatusDisplay:
    """Subscribes to the state topics of the given composites and to TaskState topics."""

    def __init__(self, node: Node, *, composites: dict[str, str], rate: Callable[[], float],
                 outcome: RunOutcome, stream: TextIO = sys.stdout, period: float = 0.5) -> None:
        self._node = node
        self._stream = stream
        self._tty = stream.isatty()
        self._rate = rate
        self._outcome = outcome
        self._safety_shown = False
        self.states: dict[str, str] = {name: '-' for name in composites}
        self.errors: dict[str, float] = {}
        self._lines_drawn = 0
        self._last_plain = ''
        self._last_plain_at = 0.0
        for name, namespace in composites.items():
            node.create_subscription(CoordinatorState, f'{namespace}/state', self._on_state, STATE_QOS)
        self._task_topics: set[str] = set()
        self._scan = node.create_timer(1.0, self._discover_tasks)
        self._timer = node.create_timer(period, self.render)

    def _on_state(self, msg: CoordinatorState) -> None:
        self.states[msg.composite] = msg.state
        self._outcome.saw_state(msg.composite, msg.state)
        if not self._tty:
            self._stream.write(f'[state] {msg.composite}: {msg.state}  <- {msg.event or "start"}\n')
            self._stream.flush()

    def show_safety(self) -> None:
        """Say once, on its own line, why the run went to Safety (red on a terminal)."""
        if self._safety_shown or not self._outcome.went_through_safety:
            return
        self._safety_shown = True
        line = self._outcome.safety_line()
        self._stream.write(f'\x1b[1;31m{line}\x1b[0m\n' if self._tty else f'{line}\n')
        self._lines_drawn = 0
        self._stream.flush()

    def _discover_tasks(self) -> None:
        for topic, types in self._node.get_topic_names_and_types():
            if 'itasc_msgs/msg/TaskState' in types and topic not in self._task_topics:
                self._task_topics.add(topic)
                self._node.create_subscription(TaskState, topic, self._on_task, DATA_QOS)

    def _on_task(self, msg: TaskState) -> None:
        self.errors[msg.task] = msg.error_norm

    def lines(self) -> list[str]:
        width = max((len(n) for n in self.states), default=8)
        out = [f'{name:<{width}}  {state}' for name, state in self.states.items()]
        if self._outcome.went_through_safety:
            out.append(f'{"rate":<{width}}  - (Safety: nothing runs)')
        else:
            out.append(f'{"rate":<{width}}  {self._rate():.1f} Hz')
        out += [f'{task:<{width}}  error {err:.4f}' for task, err in sorted(self.errors.items())]
        return out

    def render(self) -> None:
        lines = self.lines()
        if self._tty:
            if self._lines_drawn:
                self._stream.write(f'\x1b[{self._lines_drawn}F')
            self._stream.write(''.join(f'\x1b[2K{line}\n' for line in lines))
            self._lines_drawn = len(lines)
        else:
            summary = ' | '.join(lines[len(self.states):])
            now = time.monotonic()
            if summary != self._last_plain and now - self._last_plain_at >= 1.0:
                self._stream.write(f'[status] {summary}\n')
                self._last_plain, self._last_plain_at = summary, now
        self._stream.flush()

"""The bootstrap's subscriptions for the console (paper §6.1 Coordinator states, §4.1 Task and
Solver data): every composite's state topic, every Task's ``Rows/state`` and the Solver status,
fed into :class:`~.facts.RunFacts`, every transition also to the run's trace and to the display.

Task and Solver topics come from the model, so they are observed before the first tick: tapped
in this process, so that the tick pays no DDS send for the console (:mod:`..observe`), or read
over DDS from another process with a queue deep enough that the summary misses no tick the
recording holds.
"""

from __future__ import annotations

from collections import deque
from typing import Any, Callable

from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

from itasc_core.communication.qos import STATE_QOS
from itasc_msgs.msg import CoordinatorState, SolverStatus, TaskState

import itasc_core.itasc.entities.messages  # noqa: F401 - registers the samples the console reads

from ..observe import Observer
from .facts import RunFacts, Transition

__all__ = ['Watch']

#: Reliable and deep: a display that redraws must not make the summary lose ticks.
WATCH_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=2000, reliability=ReliabilityPolicy.RELIABLE)


class Watch:
    """Subscribes ``node`` to what ``facts`` needs; calls ``on_transition`` for every state change."""

    def __init__(self, node: Node, *, facts: RunFacts, solver_topics: list[str],
                 on_transition: Callable[[Transition], None],
                 elsewhere: Callable[[str], bool] = lambda topic: True) -> None:
        """``elsewhere``: see :class:`..observe.Observer`."""
        self.facts = facts
        self._on_transition = on_transition
        #: Told of every state received (:meth:`on_state`).
        self._state_listeners: list[Callable[[CoordinatorState], None]] = []
        for namespace in facts.composites.values():
            node.create_subscription(CoordinatorState, f'{namespace}/state', self._on_state, STATE_QOS)
        self.observer = Observer(node, elsewhere=elsewhere)
        # A tapped sample arrives in the tick that wrote it: it is only kept there, and goes into
        # the facts at the next poll, between ticks (issue #9: ~3 % of a 1 kHz tick otherwise).
        pending: deque[tuple[str | None, str, Any]] = deque()  # (Task, topic, TaskState) or (None, topic, SolverStatus)
        self._pending = pending
        for name, trace in facts.tasks.items():
            self.observer.samples(trace.spec.topic, TaskState,
                                  lambda topic, sample, name=name: pending.append((name, topic, sample)), qos=WATCH_QOS)
        for topic in solver_topics:
            self.observer.samples(topic, SolverStatus, lambda topic, sample: pending.append((None, topic, sample)),
                                  qos=WATCH_QOS)

    def on_state(self, listener: Callable[[CoordinatorState], None]) -> None:
        """Hand every composite state this Watch receives to ``listener`` too (the process's other
        readers of them would each be one more DDS reader per composite: a reader costs every later
        endpoint of the process, see ``bench/bench_endpoints.py``)."""
        self._state_listeners.append(listener)

    def _on_state(self, msg: CoordinatorState) -> None:
        self._on_transition(self.facts.on_state(msg))
        for listener in self._state_listeners:
            listener(msg)

    def poll(self, timer) -> None:
        """Feed the facts the Task and Solver samples that came since the last poll, and the root
        Timer's latest tick times (its window is bounded: poll it often)."""
        facts, pending = self.facts, self._pending
        while pending:
            task, topic, sample = pending.popleft()
            if task is None:
                facts.on_solver(sample, topic=topic)
            else:
                facts.on_task(task, sample)
        if timer is not None:
            facts.on_ticks(timer.stamps, timer.durations, dropped=timer.dropped)

    def count(self, timer, *, since: float | None = None, until: float | None = None) -> None:
        """The run's figures count from ``since`` (the root is Running) to ``until`` (the stop was
        commanded), ``time.monotonic()``, by the root ``timer``'s dropped ticks and program time
        (:meth:`~.facts.RunFacts.count_ticks`)."""
        self.facts.count_ticks(since=since, until=until, dropped=timer.dropped if timer is not None else 0,
                               origin=timer.origin if timer is not None else None)

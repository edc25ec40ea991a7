"""Health on ``/diagnostics`` (``diagnostic_msgs/DiagnosticArray``), where rqt_robot_monitor and
Foxglove's diagnostics panel look: one status per composite (paper §6.1: every composite's
Coordinator has a life-cycle state), at 1 Hz and within :data:`COALESCE` of a change of a level or
message.

Level and message come from the composite's life-cycle state: ``Safety`` is ERROR, Running OK,
any other state (configuring, stopping, stopped) WARN. The values are the achieved rate and the
tick time of the Timer (paper §6.2), the Solver's status and the last Safety reason (the detail of
the newest ``e_emergency``, e.g. ``Driver_panda_silent: stale on value``).

It lives in the bootstrap, next to the Timer it reads, as subscriptions to the composites' state
and event topics (written on a change only; the states through the console's readers, when it is
handed them: ``states``) and a 1 Hz timer on the bootstrap's node: none of it runs inside the
tick. The Solver status, written every tick, is not subscribed to (a reader would cost each tick a
send, see :mod:`.feed`): it is the Solver output's newest sample when a status is published.
"""

from __future__ import annotations

import statistics
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.node import Node

from itasc_core.communication.event_names import SAFETY_EVENT
from itasc_core.communication.events import EventListener, events_topic
from itasc_core.communication.qos import DATA_QOS, STATE_QOS
from itasc_msgs.msg import CoordinatorState, Event

if TYPE_CHECKING:
    from .feed import LatestSamples

__all__ = ['Diagnostics', 'level_of', 'DIAGNOSTICS_TOPIC']

DIAGNOSTICS_TOPIC = '/diagnostics'
#: The changes of this long are published together [s]. A program of 50 Tasks makes hundreds of
#: transitions as it starts, and an array of every composite's status for each of them held the
#: bootstrap's executor, hence its ticks: 64 ticks dropped in its first seconds of Running at 100 Hz.
COALESCE = 0.05


def level_of(state: str) -> bytes:
    """The diagnostic level of a life-cycle state."""
    if state.startswith('Safety'):
        return DiagnosticStatus.ERROR
    if state.startswith('Active.Run.Running'):
        return DiagnosticStatus.OK
    return DiagnosticStatus.WARN


class Diagnostics:
    """Publishes one DiagnosticStatus per composite of ``composites`` (name -> namespace); the
    Solver status is the newest of ``solvers``."""

    def __init__(self, node: Node, *, app: str, composites: dict[str, str], timer: Callable[[], Any],
                 solvers: 'LatestSamples', period: float = 1.0,
                 states: Callable[[Callable[[CoordinatorState], None]], None] | None = None) -> None:
        """``states(listener)``: hands ``listener`` every state of ``composites`` that readers of the
        process already receive (:meth:`..console.watch.Watch.on_state`); None: subscribe here."""
        self._node = node
        self._app = app
        self._timer = timer
        self.namespaces = composites
        self.states = dict.fromkeys(composites, '-')
        self.safety_reason = ''
        self._solvers = solvers
        self._shown: dict[str, tuple[bytes, str]] = {}
        self.publisher = node.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, DATA_QOS)
        if states is not None:
            states(self._on_state)
        else:
            for namespace in composites.values():
                node.create_subscription(CoordinatorState, f'{namespace}/state', self._on_state, STATE_QOS)
        # the process's event readers (its event hub), not one more reader of every event topic
        self._events = EventListener(node, topics=[events_topic(ns) for ns in composites.values()], immediate=True,
                                     on_priority=self._on_event, accept=lambda name: name == SAFETY_EVENT)
        self._periodic = node.create_timer(period, self.publish)
        self._changed = self._forced = False
        self._changes = node.create_timer(COALESCE, self._publish_changes)

    def _on_state(self, msg: CoordinatorState) -> None:
        if msg.composite in self.states:
            self.states[msg.composite] = msg.state
            self._changed = True

    def _on_event(self, msg: Event) -> None:
        if msg.detail:
            self.safety_reason = msg.detail
            self._changed = True
            self._forced |= any(s.startswith('Safety') for s in self.states.values())

    @property
    def solver_status(self) -> str:
        statuses = [msg.status for _, msg in self._solvers.items()]
        return ', '.join(statuses) if statuses else '-'

    def _publish_changes(self) -> None:
        if not self._changed:
            return
        statuses, forced = self.statuses(), self._forced
        self._changed = self._forced = False
        if forced or any(self._shown.get(s.name) != (s.level, s.message) for s in statuses):
            self.publish(statuses)

    def _timing(self) -> list[KeyValue]:
        timer = self._timer()
        durations = list(getattr(timer, 'durations', ()))[-1000:]
        rate = timer.achieved_rate() if timer is not None else 0.0
        tick = statistics.median(durations) * 1e3 if durations else float('nan')
        worst = max(durations) * 1e3 if durations else float('nan')
        return [KeyValue(key='achieved rate [Hz]', value=f'{rate:.1f}'),
                KeyValue(key='tick time median [ms]', value=f'{tick:.3f}'),
                KeyValue(key='tick time max [ms]', value=f'{worst:.3f}')]

    def statuses(self) -> list[DiagnosticStatus]:
        timing = self._timing()
        solver_status = self.solver_status
        out = []
        for name, namespace in self.namespaces.items():
            state = self.states[name]
            level = level_of(state)
            message = state if level != DiagnosticStatus.ERROR or not self.safety_reason \
                else f'Safety: {self.safety_reason}'
            out.append(DiagnosticStatus(
                level=level, name=f'{self._app}: {namespace}', message=message, hardware_id=self._app,
                values=[KeyValue(key='state', value=state), *timing,
                        KeyValue(key='solver status', value=solver_status),
                        KeyValue(key='last Safety reason', value=self.safety_reason)]))
        return out

    def publish(self, statuses: list[DiagnosticStatus] | None = None) -> None:
        statuses = self.statuses() if statuses is None else statuses
        self._shown = {s.name: (s.level, s.message) for s in statuses}
        array = DiagnosticArray(status=statuses)
        array.header.stamp = self._node.get_clock().now().to_msg()
        self.publisher.publish(array)

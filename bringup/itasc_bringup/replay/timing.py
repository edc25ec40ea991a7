"""When the replayed program handles each of its events: the gate on its event listeners.

Live, an event is handled some time after it was raised: its listener's callback waits in the
executor's queue behind the Timer's ticks, and a Coordinator takes common events at its next update
(a 200 Hz timer). A configuration switch that the Running sub-FSM commands on a Monitor's event can
take effect one, two or three ticks after that event, as the executor happened to order callbacks
and ticks. A replay that handled every event at once would switch gains ticks earlier than the run
it is compared with.

So every event the replayed program raises is matched with the recorded one (same topic, source and
name, same occurrence), and each of its receivers handles it as many gaps (see
:mod:`.recording`) after it was raised as it did live. Live, a receiver handled an event in the gap
of its recorded answer to it: the Coordinator's state change on it (``CoordinatorState.event``) or
its passing a parent's command into its composite, the status event of a Composer, Configurator or
Scheduler (``e_<c>_deployed``, ``e_<configuration>_applied``, ``e_<c>_scheduler_activated``, ...).
A Scheduler switched a Task (or any entity with stamped outputs) on or off (``e_<x>_activate``,
``e_<x>_deactivate``) in the gap before the first tick at which it computed again, or no more. A
receiver whose handling left no trace (a Monitor switched on or off), and an event without recorded
counterpart (a changed model raised it), handle it in the gap it was raised in. Each listener takes
its events in their order of arrival.
"""

from __future__ import annotations

import re
from collections import Counter, defaultdict, deque
from typing import Callable

from itasc_core.communication import event_names as names
from itasc_core.communication.event_names import ANSWERS, from_parent
from itasc_core.communication.events import Event
from rclpy.node import Node

from .recording import RecordedEvent, RecordedState, Recording

__all__ = ['EventTiming']


#: A Scheduler's command to switch one of its entities or child composites on or off.
SWITCH = re.compile(r'^e_(?P<item>\w+)_(?P<on>activate|deactivate)$')


def _answers(composite: str, name: str) -> set[str]:
    """The events with which an entity of ``composite`` may answer event ``name``."""
    configuration = name.removeprefix('e_')
    answers = {names.event(configuration, names.APPLIED), names.event(configuration, names.FAILED)}  # a Configurator's
    prefix = names.event(composite, '')
    if name.startswith(prefix):
        command = name.removeprefix(prefix)
        answers |= {names.event(composite, answer) for answer in ANSWERS.get(command, ())}
        if command.startswith('compose_'):
            answers |= {names.event(composite, names.COMPOSED), names.event(composite, names.COMPOSE_FAILED)}
        answers.add(from_parent(composite, name))  # a Coordinator passing its parent's command on
    return answers


class EventTiming:
    """The gate (``EventHub.gate``) of a replay: holds each event for each of its receivers
    until the gap it is due in. :attr:`gap` is the current gap; :meth:`release` hands over what
    became due."""

    def __init__(self, recording: Recording, *, alive: Callable[[Node], bool]) -> None:
        self.gap = -1
        self._recording = recording
        self._alive = alive
        self._occurrences: dict[tuple[str, str, str], list[RecordedEvent]] = defaultdict(list)
        self._raised_by: dict[str, list[RecordedEvent]] = defaultdict(list)
        for event in recording.events:
            self._occurrences[event.topic, event.source, event.name].append(event)
            self._raised_by[event.source].append(event)
        self._states: dict[str, list[RecordedState]] = defaultdict(list)
        for state in recording.states:
            self._states[state.topic].append(state)
        self._raised: dict[tuple, tuple[int, int]] = {}  # event -> (its occurrence, gap raised in)
        self._count: Counter[tuple[str, str, str]] = Counter()
        self._held: dict[tuple[str, str], deque[tuple[int, Node, Callable[[], None]]]] = {}
        self._latencies: dict[tuple, int] = {}
        self._computed: dict[str, list[bool]] = {}

    def __call__(self, node: Node, msg: Event, topic: str, handle: Callable[[], None]) -> bool:
        key = (topic, msg.source, msg.seq, msg.stamp.sec, msg.stamp.nanosec)
        if key not in self._raised:
            self._raised[key] = (self._count[topic, msg.source, msg.name], self.gap)
            self._count[topic, msg.source, msg.name] += 1
        occurrence, raised = self._raised[key]
        due = raised + self._latency(node, topic, msg.source, msg.name, occurrence)
        queue = self._held.setdefault((node.get_fully_qualified_name(), topic), deque())
        if not queue and due <= self.gap:
            return False
        queue.append((due, node, handle))
        return True

    def release(self) -> bool:
        """Hand over the held events that are due; whether there were any."""
        released = False
        for queue in list(self._held.values()):
            while queue and queue[0][0] <= self.gap:
                _, node, handle = queue.popleft()
                if self._alive(node):  # not destroyed meanwhile (a Task cleaned up)
                    handle()
                    released = True
        return released

    def _latency(self, node: Node, topic: str, source: str, name: str, occurrence: int) -> int:
        """How many gaps after it was raised ``node`` handled this event live (0 if unknown)."""
        key = (node.get_fully_qualified_name(), topic, source, name, occurrence)
        if key not in self._latencies:
            self._latencies[key] = self._recorded_latency(node, topic, source, name, occurrence)
        return self._latencies[key]

    def _recorded_latency(self, node: Node, topic: str, source: str, name: str, occurrence: int) -> int:
        occurrences = self._occurrences.get((topic, source, name), [])
        if occurrence >= len(occurrences):
            return 0
        event = occurrences[occurrence]
        switch = SWITCH.match(name) if node.get_name() == 'scheduler' else None
        if switch is not None:
            prefix = f'{node.get_namespace()}/{switch["item"]}/'
            if prefix not in self._computed:
                self._computed[prefix] = self._recording.computed(prefix)
            if any(self._computed[prefix]):
                return self._switched(self._computed[prefix], self._recording.gap(event.sent),
                                      on=switch['on'] == 'activate')
        until = occurrences[occurrence + 1].sent if occurrence + 1 < len(occurrences) else float('inf')
        composite = node.get_namespace().rsplit('/', 1)[-1]
        answers = _answers(composite, name)
        sent = [e.sent for e in self._raised_by[node.get_fully_qualified_name()]
                if e.name in answers and event.sent < e.sent < until]
        if node.get_name() == 'coordinator':
            sent += [s.sent for s in self._states[f'{node.get_namespace()}/state']
                     if s.event == name and event.sent < s.sent < until]
        if not sent:
            return 0
        return max(0, self._recording.gap(min(sent)) - self._recording.gap(event.sent))

    @staticmethod
    def _switched(computed: list[bool], sent: int, *, on: bool) -> int:
        """How many gaps after ``sent`` an item that ``computed`` at the recorded ticks was
        switched on (``on``) or off: it computed (or did not) from the tick after on."""
        for k in range(sent + 1, len(computed)):
            if computed[k] == on:
                return k - 1 - sent
        return 0 if on else len(computed) - 1 - sent

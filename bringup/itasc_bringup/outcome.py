"""How a run went, as the bootstrap tells it (paper §6.1 Safety; §7.2 events carry their source).

Listens to the event topic of every composite of the model for faults: ``e_emergency`` (the priority
event that puts a composite in Safety), failed life-cycle steps (``_failed``), refused connections
and Monitors that never got their data (``_nothing_received``). The first fault whose detail says
what happened is the reason of a Safety: the events raised on its way up the hierarchy carry no
detail of their own. It also tells which composites a Composer stopped on behalf of a dead composite
process, whose own final state can therefore never come; whether an operator asked for the stop
(``e_stop_requested``, from any composite's ``~/stop``); and whether every Safety was recovered
(``~/recover``: the composite reached Running again).

Exit codes of the bootstrap: :data:`EXIT_OK` for an orderly stop from Running, :data:`EXIT_SAFETY`
when the run ended in Safety (or stopped from it), :data:`EXIT_RECOVERED` when it went through
Safety, every composite was recovered to Running, and it stopped in order from there,
:data:`EXIT_NOT_STARTED` for a wrong model or a failure before the root reached Running (what was
started is stopped in order first), :data:`EXIT_ERROR` when the hierarchy did not stop in time,
:data:`EXIT_RECORDING` for a run that would have exited 0 but whose ``--record`` recording is
incomplete (its process failed or ended early: the run's verdict stands, the recording does not).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Iterable

from rclpy.node import Node

from itasc_core.communication.event_names import (CONFIGURE, CONNECTION_REFUSED, NOTHING_RECEIVED, SAFETY_EVENT,
                                                  STOP_REQUESTED, STOPPED, owner_of)
from itasc_core.communication.events import EventListener, events_topic

__all__ = ['Fault', 'RunOutcome', 'EXIT_OK', 'EXIT_ERROR', 'EXIT_NOT_STARTED', 'EXIT_SAFETY', 'EXIT_RECOVERED',
           'EXIT_RECORDING']

EXIT_OK = 0
EXIT_ERROR = 1
EXIT_NOT_STARTED = 2
EXIT_SAFETY = 3
EXIT_RECOVERED = 4
EXIT_RECORDING = 5


@dataclass(frozen=True)
class Fault:
    """An event that reports a fault: what, who raised it, on which composite, and why."""

    composite: str
    name: str
    source: str
    detail: str
    at: float

    def __str__(self) -> str:
        why = f': {self.detail}' if self.detail else ''
        return f'{self.name} from {self.source}{why}'


def _is_fault(name: str) -> bool:
    return name == SAFETY_EVENT or name.endswith(
        ('_failed', f'_{CONNECTION_REFUSED}', '_timeout', f'_{NOTHING_RECEIVED}'))


class RunOutcome:
    """The faults of a run and the composites in Safety, from every composite's event topic."""

    def __init__(self, node: Node, *, composites: dict[str, str]) -> None:
        """``composites``: name -> namespace of every composite of the model."""
        self._names = set(composites)
        self.faults: list[Fault] = []
        #: composites a Composer reported stopped in their place (their process had died)
        self.stopped_on_behalf: set[str] = set()
        #: composites told to configure (by the bootstrap, the root; by its parent, any other)
        self.configured: set[str] = set()
        #: composites seen in Safety, with the time each was first seen there
        self.in_safety: dict[str, float] = {}
        #: composites in Safety that did not reach Running again since
        self.unrecovered: set[str] = set()
        #: how many times the run came back from Safety to Running (every composite recovered)
        self.recoveries = 0
        #: who asked for the stop through a ``~/stop`` service (its name), if anyone did
        self.stop_request: str | None = None
        self._safety_told = False
        self._episode_from = 0  # the faults of the current Safety start here
        self._first_now: str | None = None  # the first composite in the current Safety
        self._said = 0  # the faults lasting_faults looked at
        self._listener = EventListener(
            node, topics=[events_topic(ns) for ns in composites.values()], immediate=True,
            on_priority=self._on_event)

    def _on_event(self, msg) -> None:
        composite = msg.source.rsplit('/', 2)[-2] if msg.source.count('/') >= 2 else ''
        if msg.name == STOP_REQUESTED and self.stop_request is None:
            self.stop_request = msg.detail or msg.source
        elif _is_fault(msg.name):
            self.faults.append(Fault(composite, msg.name, msg.source, msg.detail, time.monotonic()))
        elif (told := owner_of(msg.name, CONFIGURE)) is not None and told in self._names:
            self.configured.add(told)
        elif owner_of(msg.name, STOPPED) is not None and msg.source.endswith('/composer'):
            child = owner_of(msg.name, STOPPED)
            if child in self._names:
                self.stopped_on_behalf.add(child)

    def saw_state(self, composite: str, state: str) -> None:
        if state == 'Safety':
            self.in_safety.setdefault(composite, time.monotonic())
            if not self.unrecovered:
                self._first_now = composite
            self.unrecovered.add(composite)
        elif state.startswith('Active.Run.Running') and composite in self.unrecovered:
            self.unrecovered.discard(composite)
            if not self.unrecovered:  # the whole run is back: a later Safety is a new one
                self.recoveries += 1
                self._safety_told = False
                self._episode_from = len(self.faults)

    @property
    def went_through_safety(self) -> bool:
        return bool(self.in_safety)

    @property
    def recovered(self) -> bool:
        """Went through Safety, and every composite came back to Running since."""
        return self.went_through_safety and not self.unrecovered

    def reason(self) -> Fault | None:
        """Why the run went to Safety (the latest time): the first fault that says why, else the
        first fault."""
        faults = self.faults[self._episode_from:] or self.faults
        with_detail = [f for f in faults if f.detail]
        return (with_detail or faults or [None])[0]  # type: ignore[list-item]  # None: no fault

    def safety_line(self) -> str:
        first = self._first_now or '?'
        reason = self.reason()
        line = f'SAFETY: {first} entered Safety <- {reason if reason else "no fault event was seen"}'
        return line + (' (recovered)' if self.recovered else '')

    def new_safety_line(self) -> str | None:
        """The Safety line the first time it is asked for once the run is in Safety, else None
        (a console says why exactly once)."""
        if not self.unrecovered or self._safety_told:
            return None
        self._safety_told = True
        return self.safety_line()

    def rate_text(self, rate: float) -> str:
        """The achieved rate as a console shows it: nothing runs in Safety."""
        return '- (Safety: nothing runs)' if self.unrecovered else f'{rate:.1f} Hz'

    def lasting_faults(self, *, settled: float = 0.5) -> list[str]:
        """The faults not said yet that did not put the run in Safety within ``settled`` s (a
        composition step that failed, a refused connection): to say while the run goes on, since
        no SAFETY line will."""
        now, said = time.monotonic(), []
        while self._said < len(self.faults) and now - self.faults[self._said].at >= settled:
            fault = self.faults[self._said]
            self._said += 1
            if fault.name != SAFETY_EVENT and not self.unrecovered \
                    and all(entered < fault.at for entered in self.in_safety.values()):
                said.append(str(fault))
        return said

    def warnings(self) -> Iterable[str]:
        """Faults that did not end in Safety (e.g. a refused connection that was retried)."""
        return [str(f) for f in self.faults if f.name != SAFETY_EVENT] if not self.in_safety else []

    def exit_code(self, *, reached_running: bool) -> int:
        if not self.went_through_safety:
            return EXIT_OK  # also a stop requested before Running, in order
        if not reached_running:
            return EXIT_NOT_STARTED
        return EXIT_RECOVERED if self.recovered else EXIT_SAFETY

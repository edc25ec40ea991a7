"""Leaving Safety the paper's way (§6.1: "recovering from a Safety state requires a
reconfiguration"): what put a composite in Safety, and whether it is still there. Plain Python.

A Coordinator keeps the faults that put its composite in Safety, or came while it was there
(:class:`Faults`). Before it reconfigures, it asks whether their causes are gone
(:class:`FaultCheck`), by events (§7.2), never by calling into other entities:

* its own Composer, for the entities of its composite that raised a fault, and for child
  processes that died: ``e_<c>_check_faults`` (detail ``<n>|<source>,<source>...``), answered by
  ``e_<c>_faults_checked`` (detail ``<n>|<why the causes are still there>``, empty if gone). The
  Composer asks each of those entities ``fault_persists()``: a watchdog Monitor whether its
  condition still holds on the data that keeps flowing in Safety (a driver still silent, a NaN
  still coming in), the Robot or the Scene whether their latest input is still not finite; an
  entity that cannot tell (a Solver's infeasible problem, an exception in a computation) answers
  that it is gone, and the restart is its test: the composite enters Safety again if it is not;
* every child composite's Coordinator, which asks its own in turn: ``e_<child>_check_faults`` on
  this composite's event topic, answered by ``e_<child>_faults_checked`` on it.

A party that does not answer within :data:`CHECK_TIMEOUT` (a dead process) counts as a cause
still there.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..communication.event_names import SAFETY_EVENT

__all__ = ['CHECK_TIMEOUT', 'COMPOSER', 'Fault', 'Faults', 'FaultCheck', 'is_fault', 'check_request',
           'parse_request', 'check_answer', 'parse_answer']

#: How long the parties of a fault check may take to answer (seconds).
CHECK_TIMEOUT = 3.0
#: The party of a check that answers for the composite's own entities.
COMPOSER = 'composer'


def is_fault(name: str) -> bool:
    """Events that put a composite in Safety (see :mod:`.lifecycle`)."""
    return name == SAFETY_EVENT or name.endswith(('_failed', '_timeout', '_emergency'))


@dataclass(frozen=True)
class Fault:
    name: str
    source: str
    detail: str

    def __str__(self) -> str:
        return f'{self.name} from {self.source}' + (f': {self.detail}' if self.detail else '')


class Faults:
    """The faults of one composite's current Safety."""

    def __init__(self, namespace: str) -> None:
        self._namespace = namespace.rstrip('/')
        self.faults: list[Fault] = []

    def add(self, name: str, source: str, detail: str) -> None:
        fault = Fault(name, source, detail)
        if fault not in self.faults:
            self.faults.append(fault)

    def clear(self) -> None:
        self.faults.clear()

    def own_sources(self) -> list[str]:
        """The entities of this composite that raised a fault (their node names are
        ``<namespace>/<entity>``), for its Composer to ask."""
        return sorted({f.source for f in self.faults if f.source.rsplit('/', 1)[0] == self._namespace})


@dataclass
class FaultCheck:
    """One round of questions: which parties still owe an answer, and the causes still there."""

    number: int
    parties: set[str]
    started: float
    reasons: list[str] = field(default_factory=list)

    def answer(self, party: str, reasons: str) -> None:
        if party in self.parties:
            self.parties.discard(party)
            if reasons:
                self.reasons.append(reasons)

    def done(self, now: float) -> bool:
        """All answered, or a cause is known to be still there, or time is up."""
        return not self.parties or bool(self.reasons) or now - self.started > CHECK_TIMEOUT

    def outcome(self, now: float) -> str:
        """Why the causes are still there ('' if they are gone)."""
        if not self.reasons and self.parties and now - self.started > CHECK_TIMEOUT:
            missing = ', '.join(sorted(self.parties))
            return f'no answer within {CHECK_TIMEOUT:g} s from {missing}'
        return '; '.join(self.reasons)


def check_request(number: int, sources: list[str]) -> str:
    """The detail of ``e_<c>_check_faults``."""
    return f'{number}|{",".join(sources)}'


def parse_request(detail: str) -> tuple[str, list[str]]:
    number, _, sources = detail.partition('|')
    return number, [s for s in sources.split(',') if s]


def check_answer(number: str | int, reasons: str) -> str:
    """The detail of ``e_<c>_faults_checked``."""
    return f'{number}|{reasons}'


def parse_answer(detail: str) -> tuple[str, str]:
    number, _, reasons = detail.partition('|')
    return number, reasons

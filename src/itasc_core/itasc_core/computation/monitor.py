"""Monitors (paper §3.1, §4.1, Fig. 3): compare actual data flow with what is expected and raise a
configured event when a condition holds, e.g. ``e_max_pos_tracking_error_exc``.

The condition is plain Python (:class:`Condition`), testable without ROS; :class:`Monitor` is the
entity: configured through ROS parameters by the Configurator, switched on and off by the
Coordinator's events, evaluated by the Scheduler after the composite's computations every tick.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, Iterable

from ..communication.ports import InputPort, PortSpec
from ..entity import CompositeContext
from .functional_entity import FunctionalEntity

__all__ = ['Condition', 'Monitor', 'read_field']


@dataclass
class Condition:
    """``above``/``below`` a threshold, ``outside`` a band, ``stale`` data, ``nonfinite`` values."""

    kind: str
    threshold: float = 0.0
    low: float = -math.inf
    high: float = math.inf
    timeout: float = 0.5
    #: For ``stale``: how long the first sample may take (a driver still coming up).
    grace: float = 0.0

    def holds(self, values: Iterable[float] | None, *, age: float, seen: bool = True) -> bool:
        if self.kind == 'stale':
            return age > (self.timeout if seen else max(self.timeout, self.grace))
        if values is None:
            return False
        values = list(values)
        if self.kind == 'nonfinite':
            return any(not math.isfinite(v) for v in values)
        if self.kind == 'above':
            return any(v > self.threshold for v in values)
        if self.kind == 'below':
            return any(v < self.threshold for v in values)
        if self.kind == 'outside':
            return any(v < self.low or v > self.high for v in values)
        raise ValueError(f'unknown condition {self.kind!r}')


def read_field(msg: Any, path: str) -> list[float] | None:
    """Read ``a.b[2]``-style ``path`` from a message as a list of floats."""
    value = msg
    for part in path.replace(']', '').split('.') if path else []:
        name, _, index = part.partition('[')
        if name:
            value = getattr(value, name)
        if index:
            value = value[int(index)]
    if isinstance(value, (int, float)):
        return [float(value)]
    return [float(v) for v in value]


class Monitor(FunctionalEntity):
    """Watches one data-flow port; raises ``event`` once each time ``condition`` starts to hold."""

    PARAMETERS = {
        'field': '',
        'condition': 'above',
        'threshold': 0.0,
        'low': -math.inf,
        'high': math.inf,
        'timeout': 0.5,
        'grace': 0.0,
        'event': 'e_monitor',
        'enabled': True,
        'enable_on': [''],
        'disable_on': [''],
        'msg_type': '',
        'type': '',
        'semantics': '',
    }

    def __init__(self, name: str, *, composite: CompositeContext, parameters: dict[str, Any] | None = None,
                 watch: PortSpec | None = None) -> None:
        self._watch_spec = watch
        super().__init__(name, composite=composite, parameters=parameters)
        self._holding = False
        self._since: float | None = None  # staleness is measured from the first tick on
        self._last_update: float | None = None
        self._seen = 0
        self.raised = 0
        self._events = self.listen(topics=[composite.events_topic], on_priority=self._switch,
                                     accept=self._switches)

    def port_specs(self, params: dict[str, Any]) -> list[PortSpec]:  # type: ignore[override]
        if self._watch_spec is None:
            return []
        spec = self._watch_spec
        return [PortSpec(name='watch', direction='input', msg_type=spec.msg_type, type=spec.type,
                         semantics=spec.semantics, multiple=False)]

    def configure(self, params: dict[str, Any]) -> None:
        self.condition = Condition(kind=params['condition'], threshold=params['threshold'],
                                   low=params['low'], high=params['high'], timeout=params['timeout'],
                                   grace=params['grace'])
        self.enabled = bool(params['enabled'])
        self.event = params['event']
        self.field = params['field']
        self._on = {e for e in params['enable_on'] if e}
        self._off = {e for e in params['disable_on'] if e}

    def _switches(self, name: str) -> bool:
        return name in self._on or name in self._off

    def _switch(self, msg) -> None:
        self.enabled = msg.name in self._on
        self._holding = False
        self._since = None

    def start(self) -> None:
        self._since = self._last_update = None
        self._holding = False  # also after a recovery: a condition holding from the start is news

    @property
    def watch(self) -> InputPort:
        return self.inputs['watch']

    def update(self, t: float) -> None:
        for msg in self._events.drain():
            self._switch(msg)
        if not self.enabled:
            return
        port = self.watch
        now = time.monotonic()
        if self._since is not None and self._last_update is not None \
                and now - self._last_update > self.condition.timeout / 2:
            # This process did not run for a while (its executor was busy, e.g. destroying a
            # composite's nodes): samples that arrived meanwhile are still queued, so the time
            # nobody listened is not the data's age.
            self._since += now - self._last_update
        self._last_update = now
        if port.received != self._seen or self._since is None:
            self._seen, self._since = port.received, now
        needs_values = self.condition.kind != 'stale' and port.latest is not None
        values = read_field(port.latest, self.field) if needs_values else None
        holds = self.condition.holds(values, age=now - self._since, seen=port.received > 0)
        if holds and not self._holding:
            self.raised += 1
            self.raise_event(self.event, detail=f'{self.entity_name}: {self.condition.kind} on {self.field or "value"}')
        self._holding = holds

    def fault_persists(self) -> str | None:
        """Whether the condition still holds, on the data that arrived until now (the Scheduler runs
        no Monitor in Safety, but the data keeps flowing: a Driver keeps reporting what it measures).
        Asked before a recovery from Safety (:mod:`..coordination.recovery`); the reason, or None."""
        port = self.watch
        if self.condition.kind == 'stale':
            if port.received_at is None:
                return f'nothing ever came on {", ".join(port.sources) or "its input"}'
            age = time.monotonic() - port.received_at
            if age > self.condition.timeout:
                return f'stale: nothing came on {", ".join(port.sources)} for {age:.1f} s'
            return None
        if port.latest is None:
            return None
        values = read_field(port.latest, self.field)
        if self.condition.holds(values, age=0.0):
            return f'{self.condition.kind} on {self.field or "value"}: {values}'
        return None

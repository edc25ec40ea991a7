"""Monitors (paper §3.1, §4.1, Fig. 3): compare actual data flow with what is expected and raise a
configured event when a condition holds, e.g. ``e_max_pos_tracking_error_exc``.

The condition is a registered kind (:mod:`.conditions`, plain Python, testable without ROS);
:class:`Monitor` is the entity: configured through ROS parameters by the Configurator (its own and
its condition's, e.g. ``threshold``), switched on and off by the Coordinator's events, evaluated by
the Scheduler after the composite's computations every tick.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Mapping
from typing import Any

import numpy as np
from pydantic import Field
from rcl_interfaces.msg import SetParametersResult
from rclpy.parameter import Parameter

from ..communication.event_names import NOTHING_RECEIVED, SAFETY_EVENT, event
from ..communication.ports import InputPort, PortSpec
from ..entity import CompositeContext
from ..kinds import with_kind
from .conditions import CONDITIONS
from .functional_entity import OUTSIDE, FunctionalEntity
from .parameters import ParameterModel

__all__ = ['Monitor', 'read_field']


@functools.lru_cache(maxsize=256)
def _steps(path: str) -> tuple[tuple[str, int | None], ...]:
    """``a.b[2]`` as ``(('a', None), ('b', 2))``: parsed once per path, not every tick."""
    steps = []
    for part in path.replace(']', '').split('.') if path else []:
        name, _, index = part.partition('[')
        steps.append((name, int(index) if index else None))
    return tuple(steps)


def read_field(msg: Any, path: str) -> list[float]:
    """Read ``a.b[2]``-style ``path`` from a message (or its sample) as a list of floats."""
    value = msg
    for name, index in _steps(path):
        if name:
            value = getattr(value, name)
        if index is not None:
            value = value[index]
    if isinstance(value, (int, float)):
        return [float(value)]
    if isinstance(value, np.ndarray):
        return value.tolist()
    return [float(v) for v in value]


class Monitor(FunctionalEntity):
    """Watches one data-flow port; raises ``event`` once each time ``condition`` starts to hold."""

    class Parameters(ParameterModel):
        field: str = Field(default='', frozen=True)
        """What it reads of each sample: ``a.b[2]``-style path ('': the sample itself)."""
        condition: str = Field(default='above', frozen=True)
        """When it raises its event: a registered condition (its own parameters follow)."""
        event: str = Field(default='e_monitor', pattern=r'^e_[A-Za-z0-9_]+$', frozen=True)
        """The event it raises once the condition starts to hold."""
        enabled: bool = True
        """Whether it runs from the start; set while it runs, an operator's switch (until the next
        switching event)."""
        enable_on: list[str] = Field(default_factory=list, frozen=True)
        """The events that switch it on."""
        disable_on: list[str] = Field(default_factory=list, frozen=True)
        """The events that switch it off."""

    @classmethod
    def parameter_model(cls, values: Mapping[str, Any]) -> type[ParameterModel]:
        return with_kind(cls.Parameters, CONDITIONS, field='condition', values=values)

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

    def port_specs(self, params: Any) -> list[PortSpec]:  # type: ignore[override]
        if self._watch_spec is None:
            return []
        spec = self._watch_spec
        return [PortSpec(name='watch', direction='input', msg_type=spec.msg_type, type=spec.type,
                         semantics=spec.semantics, multiple=False)]

    def configure(self, params: Any) -> None:
        self.condition = CONDITIONS[params.condition](params)
        self.condition_name = params.condition
        #: a condition on the arrival of data: its timeout also tells a pause of this process
        self._timeout: float | None = getattr(params, 'timeout', None)
        if not hasattr(self, 'enabled'):  # how it starts; then the FSM's events switch it (see _check_parameters)
            self.enabled = params.enabled
        self.event = params.event
        self.field = params.field
        self._on = set(params.enable_on)
        self._off = set(params.disable_on)

    def _check_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        """Another threshold leaves the Monitor on or off as the FSM switched it; ``enabled`` set
        explicitly switches it."""
        switch = [bool(p.value) for p in parameters if p.name == 'enabled']
        if switch and not switch[-1] and self.event == SAFETY_EVENT and self.cause == OUTSIDE:
            return SetParametersResult(successful=False, reason=f'{self.entity_name} raises {SAFETY_EVENT}: a safety '
                                       'function is not switched off from outside while it runs')
        result = super()._check_parameters(parameters)
        if result.successful and switch:
            self._set_enabled(switch[-1])
        return result

    def _switches(self, name: str) -> bool:
        return name in self._on or name in self._off

    def _switch(self, msg) -> None:
        self._set_enabled(msg.name in self._on)

    def _set_enabled(self, on: bool) -> None:
        self.enabled = on
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
        if self._timeout is not None and self._since is not None and self._last_update is not None \
                and now - self._last_update > self._timeout / 2:
            # This process did not run for a while (its executor was busy, e.g. destroying a
            # composite's nodes): samples that arrived meanwhile are still queued, so the time
            # nobody listened is not the data's age.
            self._since += now - self._last_update
        self._last_update = now
        if port.received != self._seen or self._since is None:
            self._seen, self._since = port.received, now
        needs_values = self.condition.reads_values and port.latest is not None
        values = read_field(port.latest, self.field) if needs_values else None
        holds = self.condition.holds(values, age=now - self._since, seen=port.received > 0)
        if not isinstance(holds, (bool, np.bool_)):  # 'maybe' or None is no answer: a plugin's error
            raise TypeError(f"condition '{self.condition_name}' of {self.entity_name} answered {holds!r}, "
                            'not True or False')
        if holds and not self._holding:
            self.raised += 1
            self.raise_event(self.event, detail=f'{self.entity_name}: {self.condition_name} on {self.field or "value"}')
        self._holding = holds

    def disengage(self) -> None:
        """Stopping: a Monitor of the arrival of data (``stale``) that watched for longer than its
        timeout and never got a sample says so (``e_<monitor>_nothing_received``), since its grace
        for a first sample may outlast a short run, which then ends without a fault (e.g. a Driver
        whose driver never reported)."""
        port = self.watch
        if not self.enabled or self.condition.reads_values or self._timeout is None or self._since is None \
                or port.received or self.raised:
            return
        watched = time.monotonic() - self._since
        if watched > self._timeout:
            self.raise_event(event(self.entity_name, NOTHING_RECEIVED),
                             detail=f'nothing came on {", ".join(port.sources)} in the {watched:.1f} s it watched')

    def fault_persists(self) -> str | None:
        """Whether the condition still holds, on the data that arrived until now (the Scheduler runs
        no Monitor in Safety, but the data keeps flowing: a Driver keeps reporting what it measures).
        Asked before a recovery from Safety (:mod:`..coordination.recovery`); the reason, or None."""
        port = self.watch
        if not self.condition.reads_values:
            if port.received_at is None:
                return f'nothing ever came on {", ".join(port.sources) or "its input"}'
            age = time.monotonic() - port.received_at
            if self.condition.holds(None, age=age):
                return f'{self.condition_name}: nothing came on {", ".join(port.sources)} for {age:.1f} s'
            return None
        if port.latest is None:
            return None
        values = read_field(port.latest, self.field)
        if self.condition.holds(values, age=0.0):
            return f'{self.condition_name} on {self.field or "value"}: {values}'
        return None


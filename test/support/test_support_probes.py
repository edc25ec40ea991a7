"""Functional Entity kinds for the runtime tests: they record when the Scheduler runs them and
can raise events on request. Importing this module registers them (kind ``test_support_probes:OrderProbe``)."""

from __future__ import annotations

from itasc_core.composition.registry import register_kind
from itasc_core.computation.functional_entity import FunctionalEntity
from itasc_core.computation.parameters import ParameterModel

#: (tick time, entity fully qualified name), appended by every OrderProbe.update.
CALLS: list[tuple[float, str]] = []


class OrderProbe(FunctionalEntity):
    """Records every call of update; raises ``raise_on_tick`` (priority) on tick ``at_tick``."""

    class Parameters(ParameterModel):
        raise_on_tick: str = ''
        """The event raised at tick ``at_tick`` ('': none)."""
        at_tick: int = 0
        """The tick (counted from 1) that raises ``raise_on_tick``."""

    def configure(self, params: Parameters) -> None:
        self.raise_name, self.at_tick = params.raise_on_tick, params.at_tick
        self.ticks = 0
        self.activations = self.deactivations = 0

    def activate(self) -> None:
        self.activations += 1

    def deactivate(self, t: float) -> None:
        self.deactivations += 1

    def update(self, t: float) -> None:
        self.ticks += 1
        CALLS.append((t, self.get_fully_qualified_name()))
        if self.raise_name and self.ticks == self.at_tick:
            self.raise_event(self.raise_name, priority=True, detail='raised by test probe')


register_kind('test_support_probes:OrderProbe', OrderProbe)

"""Bring a composite hierarchy up in this process with real rclpy nodes over real DDS, and watch
every Coordinator's state."""

from __future__ import annotations

import time
from typing import Callable

import rclpy
from rclpy.signals import SignalHandlerOptions

from itasc_core.communication.event_names import CONFIGURE, event
from itasc_core.communication.events import EventListener, EventRaiser
from itasc_core.composition.composer import Composer, bring_up
from itasc_core.composition.deployment import Runtime, make_executor
from itasc_core.composition.model import CompositeModel
from itasc_core.entity import CompositeContext
from ros_teardown import destroy_all


class Hierarchy:
    def __init__(self, model: dict) -> None:
        self.model = CompositeModel.model_validate(model)
        rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
        self.executor = make_executor()
        self.root = CompositeContext(name=self.model.name, namespace=f'/{self.model.name}')
        self.runtime = Runtime(executor=self.executor, namespace=self.root.namespace)
        self.node = rclpy.create_node('test_driver', namespace=self.root.namespace)
        self.executor.add_node(self.node)
        self.events: list = []
        self._raisers: dict[str, EventRaiser] = {}
        self.composer = bring_up(model=self.model, context=self.root, runtime=self.runtime)
        self.coordinators: dict[str, object] = {}
        self.stamps: dict[str, list[tuple[float, str]]] = {}

    def listen(self, namespace: str) -> None:
        EventListener(self.node, topics=[f'{namespace}/events'], immediate=True, on_priority=self.events.append)

    def raise_event(self, name: str, namespace: str | None = None, detail: str = '') -> None:
        namespace = namespace or self.root.namespace
        if namespace not in self._raisers:
            self._raisers[namespace] = EventRaiser(self.node, topic=f'{namespace}/events')
            self.spin_until(lambda: self._raisers[namespace].publisher.get_subscription_count() > 0, timeout=5)
        self._raisers[namespace].raise_event(name, detail=detail)

    def composers(self, composer: Composer | None = None):
        composer = composer or self.composer
        yield composer
        for child in list(composer.children.values()):
            if child is not None:
                yield from self.composers(child)

    def _track(self) -> None:
        for composer in self.composers():
            self.coordinators[composer.composite.name] = composer.coordinator
        # and those of composites removed since: their last states may have come in the same spin
        for name, coordinator in self.coordinators.items():
            seen = self.stamps.setdefault(name, [])
            for state, _event, entered_at in coordinator.history[len(seen):]:
                # when it was entered: states entered in one spin are seen together, in any order
                seen.append((entered_at, state))

    def states(self, name: str) -> list[str]:
        return [s for _, s in self.stamps[name]]

    def state(self, name: str) -> str:
        return self.coordinators[name].state

    def spin_until(self, condition: Callable[[], bool], *, timeout: float = 20.0) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.005)
            self._track()
            self.runtime.reap()
            if condition():
                return True
        return False

    def spin_for(self, seconds: float) -> None:
        self.spin_until(lambda: False, timeout=seconds)

    def start(self) -> None:
        self.spin_until(lambda: False, timeout=0.05)
        self.raise_event(event(self.root.name, CONFIGURE))

    def close(self) -> None:
        self.runtime.reap()
        self.runtime.shutdown()
        destroy_all(self.executor, *(node for composer in list(self.composers())
                                     for node in (composer.coordinator, composer.configurator, composer)))

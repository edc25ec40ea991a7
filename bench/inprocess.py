"""An application brought up in this process as ``bootstrap --deploy single`` does (paper §6.1:
the root's Coordinator, Composer and Configurator, then ``e_<root>_configure``), for the
benchmarks that time its ticks."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Callable

__all__ = ['Running', 'run_application', 'spin_for']


@dataclass
class Running:
    """An application whose every composite reached Running."""

    executor: Any
    node: Any
    composer: Any
    runtime: Any
    raiser: Any
    name: str

    def stop(self, *, timeout: float = 20.0) -> None:
        """Stop the hierarchy in order (``e_<root>_stop``) and shut rclpy down."""
        import rclpy
        from itasc_core.communication.event_names import STOP, event
        self.raiser.raise_event(event(self.name, STOP))
        deadline = time.monotonic() + timeout
        while not self.composer.coordinator.state.endswith('NotifyStopped') and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.01)
            self.runtime.reap()
        rclpy.try_shutdown()


def run_application(spec, *, before_configure: Callable[[Any, Any], None] | None = None,
                    poll: float = 0.01) -> Running:
    """Bring up the composition model ``spec`` (rclpy initialised here) and return once every
    composite is Running; ``before_configure(node, composer)`` runs just before the configure
    event (e.g. to start the visualization, as the bootstrap does)."""
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    from itasc_core.communication.event_names import CONFIGURE, event
    from itasc_core.communication.events import EventRaiser
    from itasc_core.composition.composer import bring_up
    from itasc_core.composition.deployment import Runtime, make_executor
    from itasc_core.composition.model import walk
    from itasc_core.entity import CompositeContext

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    executor = make_executor()
    root = CompositeContext(name=spec.name, namespace=f'/{spec.name}')
    runtime = Runtime(executor=executor, namespace=root.namespace)
    node = rclpy.create_node('bench', namespace=root.namespace)
    executor.add_node(node)
    composer = bring_up(model=spec, context=root, runtime=runtime)
    if before_configure is not None:
        before_configure(node, composer)
    raiser = EventRaiser(node, topic=root.events_topic)
    raiser.raise_event(event(spec.name, CONFIGURE))  # the root's Coordinator, in this process: by its event hub

    def coordinators(c=composer):
        yield c.coordinator
        for child in c.children.values():
            yield from coordinators(child)

    composites = sum(1 for _ in walk(spec))
    while not all(c.state.startswith('Active.Run.Running') for c in coordinators()) \
            or len(list(coordinators())) < composites:
        executor.spin_once(timeout_sec=poll)
    return Running(executor=executor, node=node, composer=composer, runtime=runtime, raiser=raiser,
                   name=spec.name)


def spin_for(executor, seconds: float) -> None:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.01)

"""Events are never lost (paper §7.2): 20 entities each raising 500 events as fast as they can."""

from __future__ import annotations

import threading
import time

import rclpy
from rclpy.signals import SignalHandlerOptions

from itasc_core.communication.events import EventListener, EventRaiser
from itasc_core.composition.deployment import make_executor
from ros_teardown import destroy_all

SOURCES, EVENTS = 20, 500


def test_no_event_lost_and_order_kept_per_source():
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    executor = make_executor()
    try:
        sink = rclpy.create_node('coordinator', namespace='/flood')
        listener = EventListener(sink, topics=['/flood/events'])
        executor.add_node(sink)
        raisers = []
        for i in range(SOURCES):
            node = rclpy.create_node(f'entity_{i}', namespace='/flood')
            raisers.append(EventRaiser(node, topic='/flood/events'))
            executor.add_node(node)
        deadline = time.monotonic() + 10
        while any(r.publisher.get_subscription_count() == 0 for r in raisers) and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.01)

        def flood(i: int, raiser: EventRaiser) -> None:
            for n in range(EVENTS):
                raiser.raise_event(f'e_{i}_{n}')

        # Every entity raises from its own thread while the receiver keeps spinning.
        threads = [threading.Thread(target=flood, args=(i, r)) for i, r in enumerate(raisers)]
        for thread in threads:
            thread.start()
        received = []
        deadline = time.monotonic() + 60
        while len(received) < SOURCES * EVENTS and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.01)
            received += listener.drain()
        for thread in threads:
            thread.join()
        assert len(received) == SOURCES * EVENTS
        assert listener.lost == 0
        for i in range(SOURCES):
            mine = [m for m in received if m.source == f'/flood/entity_{i}']
            assert [m.seq for m in mine] == list(range(1, EVENTS + 1))
            assert [m.name for m in mine] == [f'e_{i}_{n}' for n in range(EVENTS)]
    finally:
        destroy_all(executor)

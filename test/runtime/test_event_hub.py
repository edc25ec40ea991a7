"""The process's event hub (itasc_core.communication.event_hub): the entities of a process share
one DDS reader and one DDS writer per event topic, each still gets every event in order, and a
destroyed entity gets none and leaves no reader behind."""

from __future__ import annotations

import time

import pytest
import rclpy
import rclpy.executors
from rclpy.signals import SignalHandlerOptions

from itasc_core.communication.events import Event, EventRaiser
from itasc_core.communication.qos import EVENT_QOS
from itasc_core.composition.deployment import Runtime, make_executor
from itasc_core.entity import CompositeContext, Entity
from ros_teardown import destroy_all

TOPIC = '/hub/events'


@pytest.fixture
def world():
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    executor = make_executor()
    runtime = Runtime(executor=executor, namespace='/hub')
    source = rclpy.create_node('source', namespace='/elsewhere')
    executor.add_node(source)
    yield executor, runtime, source
    destroy_all(executor)


def spin_until(executor, condition, timeout: float = 10.0) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end and not condition():
        executor.spin_once(timeout_sec=0.01)
    return condition()


def test_entities_of_a_process_share_one_reader_and_each_gets_every_event_in_order(world):
    executor, runtime, source = world
    composite = CompositeContext(name='hub', namespace='/hub')
    received: dict[str, list] = {}
    entities = []
    for i in range(5):
        entity = Entity(f'entity_{i}', composite=composite)
        entity.listen(topics=[TOPIC], immediate=True, on_priority=received.setdefault(entity.entity_name, []).append)
        runtime.add(entity)
        entities.append(entity)
    assert source.count_subscribers(TOPIC) == 1, 'five listeners, one DDS reader'
    raiser = EventRaiser(source, topic=TOPIC)
    assert spin_until(executor, lambda: raiser.publisher.get_subscription_count() == 1)
    for n in range(200):
        raiser.raise_event(f'e_{n}')
    assert spin_until(executor, lambda: all(len(r) == 200 for r in received.values())), \
        {name: len(r) for name, r in received.items()}
    for events in received.values():
        assert [m.seq for m in events] == list(range(1, 201))

    # a destroyed entity gets nothing more; the others still get everything
    gone = entities.pop()
    runtime.retire([gone])
    runtime.reap()
    raiser.raise_event('e_after')
    assert spin_until(executor, lambda: all(len(received[e.entity_name]) == 201 for e in entities))
    assert len(received[gone.entity_name]) == 200

    # the last listener gone, the process no longer reads the topic at all
    runtime.retire(entities)
    runtime.reap()
    assert spin_until(executor, lambda: raiser.publisher.get_subscription_count() == 0)
    assert source.count_subscribers(TOPIC) == 0


def test_an_entity_destroyed_by_an_earlier_listener_of_the_same_event_is_not_called(world):
    executor, runtime, source = world
    composite = CompositeContext(name='hub', namespace='/hub')
    first, second = Entity('first', composite=composite), Entity('second', composite=composite)
    heard: list[str] = []
    # the first listener ends the second one's listening while the event is being handed out
    first.listen(topics=[TOPIC], immediate=True, on_priority=lambda m: (heard.append('first'), second.destroy_node()))
    second.listen(topics=[TOPIC], immediate=True, on_priority=lambda m: heard.append('second'))
    runtime.add(first)
    raiser = EventRaiser(source, topic=TOPIC)
    assert spin_until(executor, lambda: raiser.publisher.get_subscription_count() == 1)
    raiser.raise_event('e_once')
    assert spin_until(executor, lambda: heard)
    executor.spin_once(timeout_sec=0.1)
    assert heard == ['first']


def test_an_event_raised_in_the_process_reaches_its_listeners_at_the_next_flush_once_and_in_order(world):
    """Issue #9: no round trip through DDS for the process's own events. A flush (the Timer's,
    after a tick) delivers them at once; their copies from DDS are dropped; an event a listener
    raises while one is delivered comes after it; an outside process's events still arrive."""
    executor, runtime, source = world
    composite = CompositeContext(name='hub', namespace='/hub')
    heard: list[str] = []
    first, second = Entity('first', composite=composite), Entity('second', composite=composite)
    answer = EventRaiser(first, topic=TOPIC)
    first.listen(topics=[TOPIC], immediate=True,
                 on_priority=lambda m: (heard.append(f'first {m.name}'),
                                        m.name == 'e_ping' and answer.raise_event('e_pong')))
    second.listen(topics=[TOPIC], immediate=True, on_priority=lambda m: heard.append(f'second {m.name}'))
    runtime.add(first, second)
    raiser = EventRaiser(source, topic=TOPIC)
    assert spin_until(executor, lambda: raiser.publisher.get_subscription_count() == 1)
    hub = runtime.events

    raiser.raise_event('e_ping')
    assert heard == []  # raised, not yet delivered
    hub.flush()
    assert heard == ['first e_ping', 'second e_ping', 'first e_pong', 'second e_pong']
    executor.spin_once(timeout_sec=0.2)  # the copies from DDS come back...
    spin_until(executor, lambda: False, timeout=0.3)
    assert len(heard) == 4  # ...and are dropped

    # an event of another process, over DDS
    other = rclpy.Context()
    rclpy.init(context=other, signal_handler_options=SignalHandlerOptions.NO)
    try:
        outside = rclpy.create_node('outside', context=other)
        outside_raiser = EventRaiser(outside, topic=TOPIC)
        deadline = time.monotonic() + 10
        while outside_raiser.publisher.get_subscription_count() < 1 and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.01)
        outside_raiser.raise_event('e_outside')
        assert spin_until(executor, lambda: 'second e_outside' in heard)
        assert heard[4:] == ['first e_outside', 'second e_outside']
        outside.destroy_node()
    finally:
        rclpy.try_shutdown(context=other)


def test_the_raisers_of_a_process_share_one_writer_per_topic_and_it_leaves_with_the_last_of_them(world):
    """Every DDS endpoint of a process makes the later ones dearer to create (bring-up of large
    programs): a process has one event writer per topic, not one per entity. Outside the process
    every event still arrives, each naming the entity that raised it; once the last raiser of a
    topic is destroyed, its writer is gone from the graph."""
    executor, runtime, source = world
    composite = CompositeContext(name='hub', namespace='/hub')
    entities = [Entity(f'entity_{i}', composite=composite) for i in range(4)]
    runtime.add(*entities)
    topic = composite.events_topic
    assert source.count_publishers(topic) == 1, 'four raisers, one DDS writer'

    other = rclpy.Context()
    rclpy.init(context=other, signal_handler_options=SignalHandlerOptions.NO)
    try:
        outside = rclpy.create_node('outside', context=other)
        heard: list[tuple[str, str, int]] = []
        outside.create_subscription(Event, topic, lambda m: heard.append((m.source, m.name, m.seq)), EVENT_QOS)
        outside_executor = rclpy.executors.SingleThreadedExecutor(context=other)
        outside_executor.add_node(outside)
        assert spin_until(outside_executor, lambda: source.count_subscribers(topic) >= 1)
        assert spin_until(outside_executor, lambda: entities[0]._raiser.publisher.get_subscription_count() >= 1)
        for n in range(3):
            for entity in entities:
                entity.raise_event(f'e_{n}')
        assert spin_until(outside_executor, lambda: len(heard) == 12), heard
        for entity in entities:
            assert [(name, seq) for who, name, seq in heard if who == entity.get_fully_qualified_name()] \
                == [('e_0', 1), ('e_1', 2), ('e_2', 3)]

        runtime.retire(entities[1:])
        runtime.reap(wait=True)
        assert source.count_publishers(topic) == 1, 'one raiser left: the writer stays'
        entities[0].raise_event('e_last')
        assert spin_until(outside_executor, lambda: heard[-1][1] == 'e_last')
        runtime.retire(entities[:1])
        runtime.reap(wait=True)
        assert spin_until(outside_executor, lambda: outside.count_publishers(topic) == 0)
        outside_executor.shutdown()
        outside.destroy_node()
    finally:
        rclpy.try_shutdown(context=other)


def test_a_raiser_destroyed_before_its_entity_is_let_go_of(world):
    """A Composer raises on the topic of each child composite in a process of its own, and lets go
    of that raiser when the child is removed: a long run that adds and removes Tasks keeps none."""
    import gc
    import weakref

    executor, runtime, source = world
    composite = CompositeContext(name='hub', namespace='/hub')
    entity = Entity('composer', composite=composite)
    runtime.add(entity)
    raiser = entity.raiser(topic='/hub/child/events')
    raiser.raise_event('e_child_bind')
    gone = weakref.ref(raiser)
    entity.destroy_raiser(raiser)
    del raiser
    gc.collect()
    assert gone() is None, 'the entity still holds the raiser it destroyed'
    assert spin_until(executor, lambda: source.count_publishers('/hub/child/events') == 0)

"""The process's writers of rclpy's per-node topics (itasc_core.communication.process_writers):
however many entities a process hosts, it has the same few ``/rosout`` and ``/parameter_events``
writers, and what each entity logs or changes still reaches those topics under its own name."""

from __future__ import annotations

import time

import pytest
import rclpy
import rclpy.executors
from rcl_interfaces.msg import Log, ParameterEvent
from rclpy.qos import qos_profile_parameter_events
from rclpy.signals import SignalHandlerOptions

from itasc_core.composition.deployment import Runtime, make_executor
from itasc_core.entity import CompositeContext, Entity
from ros_teardown import destroy_all

ROOT = CompositeContext(name='proc', namespace='/proc')


@pytest.fixture
def world():
    """A process (a Runtime started for ``/proc``) and, in a participant of its own, an observer
    of ``/rosout`` and ``/parameter_events``."""
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    executor = make_executor()
    runtime = Runtime(executor=executor, namespace=ROOT.namespace)
    other = rclpy.Context()
    rclpy.init(context=other, signal_handler_options=SignalHandlerOptions.NO)
    observer = rclpy.create_node('observer', context=other, enable_rosout=False)
    observer_executor = rclpy.executors.SingleThreadedExecutor(context=other)
    observer_executor.add_node(observer)
    logs: list[Log] = []
    changes: list[ParameterEvent] = []
    observer.create_subscription(Log, '/rosout', logs.append, 1000)
    observer.create_subscription(ParameterEvent, '/parameter_events', changes.append, qos_profile_parameter_events)
    yield executor, runtime, observer, observer_executor, logs, changes
    destroy_all(observer_executor, observer, context=other)
    destroy_all(executor)


def spin_until(executors, condition, timeout: float = 10.0) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end and not condition():
        for executor in executors:
            executor.spin_once(timeout_sec=0.01)
    return condition()


def writers_of(observer, topic: str) -> int:
    """The writers of ``topic`` on nodes of the process (all live in ``/proc``)."""
    return len([info for info in observer.get_publishers_info_by_topic(topic)
                if f'{info.node_namespace}/{info.node_name}'.startswith(ROOT.namespace)])


def test_a_process_has_the_same_few_rosout_and_parameter_event_writers_whatever_its_number_of_entities(world):
    """Fast DDS pairs every new endpoint of a process with every local one of the other kind, so a
    writer per entity made the bring-up of a large program grow with the square of its size."""
    executor, runtime, observer, observer_executor, logs, changes = world
    spin = [executor, observer_executor]
    few = [Entity(f'e{i}', composite=ROOT) for i in range(2)]
    runtime.add(*few)
    time.sleep(0.5)  # the graph settles
    spin_until(spin, lambda: False, timeout=0.5)
    baseline = writers_of(observer, '/rosout'), writers_of(observer, '/parameter_events')

    child = ROOT.child('child')
    many = [Entity(f'e{i}', composite=ROOT) for i in range(2, 6)] + [Entity(f'c{i}', composite=child)
                                                                      for i in range(6)]
    runtime.add(*many)
    spin_until(spin, lambda: False, timeout=1.0)
    assert (writers_of(observer, '/rosout'), writers_of(observer, '/parameter_events')) == baseline, \
        'twelve entities, no more writers than with two'
    assert baseline[0] <= 2 and baseline[1] <= 3, baseline  # the process node's and the event hub's


def test_every_entity_still_logs_to_rosout_and_announces_its_parameter_changes_under_its_own_name(world):
    executor, runtime, observer, observer_executor, logs, changes = world
    spin = [executor, observer_executor]
    child = ROOT.child('child')
    entities = [Entity('a', composite=ROOT), Entity('b', composite=child), Entity('c', composite=child)]
    runtime.add(*entities)
    assert spin_until(spin, lambda: writers_of(observer, '/rosout') >= 1)
    spin_until(spin, lambda: False, timeout=1.0)  # matched both ways

    for entity in entities:
        entity.get_logger().warning(f'hello from {entity.entity_name}')
        entity.declare_parameter('gain', 1.0)
        entity.set_parameters([rclpy.parameter.Parameter('gain', value=2.5)])
    names = {'proc.a', 'proc.child.b', 'proc.child.c'}
    assert spin_until(spin, lambda: {log.name for log in logs if log.msg.startswith('hello')} == names), \
        [(log.name, log.msg) for log in logs]
    assert sorted((log.name, log.msg) for log in logs if log.msg.startswith('hello')) == [
        ('proc.a', 'hello from a'), ('proc.child.b', 'hello from b'), ('proc.child.c', 'hello from c')]
    fqns = {'/proc/a', '/proc/child/b', '/proc/child/c'}
    assert spin_until(spin, lambda: {e.node for e in changes if any(
        p.name == 'gain' and p.value.double_value == 2.5 for p in e.changed_parameters)} == fqns), \
        [(e.node, [p.name for p in e.changed_parameters]) for e in changes]

    # one entity gone, the others still log
    runtime.retire(entities[1:2])
    runtime.reap(wait=True)
    for entity in (entities[0], entities[2]):
        entity.get_logger().warning(f'still here: {entity.entity_name}')
    assert spin_until(spin, lambda: {log.name for log in logs if log.msg.startswith('still here')}
                      == {'proc.a', 'proc.child.c'}), [(log.name, log.msg) for log in logs]

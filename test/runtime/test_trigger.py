"""The trigger of a composite in another process (itasc_core.communication.trigger): it carries
the newest samples of the parent process's outputs the child reads, which the child's inputs get
before its tick, with no DDS message of their own. The parent and the child are two ROS contexts
here (two processes' worth of DDS participants, each with its own bus)."""

from __future__ import annotations

import time

import rclpy
from std_msgs.msg import Float64

from itasc_core.communication.cdr import sample_decoder, serialize
from itasc_core.communication.ports import InputPort, OutputPort, PortSpec
from itasc_core.communication.qos import DATA_QOS
from itasc_core.communication.samples import Float64Sample
from itasc_core.communication.trigger import trigger_of
from itasc_core.coordination.scheduler import Scheduler
from itasc_core.entity import CompositeContext
from itasc_msgs.msg import Trigger
from ros_teardown import two_contexts

TOPIC = '/carry/itasc/Scene/relation_T'
SPEC = PortSpec(name='relation', direction='output', msg_type=Float64, type='signal', id=TOPIC)
CHILD = CompositeContext(name='T', namespace='/carry/itasc/T', parent_namespace='/carry/itasc')


def _spin_until(condition, *executors, timeout: float = 10.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and not condition():
        for executor in executors:
            executor.spin_once(timeout_sec=0.01)
    return condition()


def test_the_parents_trigger_carries_each_new_sample_of_an_output_its_child_reads():
    """The parent's Scheduler triggers the child in another process with what the output wrote
    since the last trigger (nothing again if it did not write)."""
    with two_contexts('/carry') as (executor, _, theirs, other):
        parent = Scheduler(composite=CompositeContext(name='itasc', namespace='/carry/itasc'))
        executor.add_node(parent)
        output = OutputPort(parent, SPEC)
        parent.add_remote_child('T', CHILD.namespace)
        assert parent.carry('T', TOPIC) and not parent.carry('Elsewhere', TOPIC)
        child_node = rclpy.create_node('scheduler', namespace=CHILD.namespace, context=other)
        theirs.add_node(child_node)
        decode = sample_decoder(Trigger)
        triggers: list = []
        child_node.create_subscription(Trigger, CHILD.trigger_topic, lambda raw: triggers.append(decode(raw)),
                                       DATA_QOS, raw=True)
        parent.active = True
        assert _spin_until(lambda: parent.count_subscribers(CHILD.trigger_topic) > 0, executor, theirs)
        output.write(Float64Sample(2.5))
        parent.tick(1.0)
        parent.tick(1.01)  # nothing new written: nothing carried
        assert _spin_until(lambda: len(triggers) == 2, executor, theirs)
        first, second = triggers
        decode_value = sample_decoder(Float64)
        assert first.t == 1.0 and [(topic, decode_value(data).data) for topic, data in first.carried()] == [
            (TOPIC, 2.5)]
        assert second.t == 1.01 and list(second.carried()) == []


def test_a_child_hands_what_its_trigger_carries_to_its_inputs_before_it_ticks():
    """The child's input of a carried topic has no DDS subscription: it gets the sample from the
    trigger, before the tick the trigger starts."""
    with two_contexts('/carry') as (executor, runtime, theirs, other):
        child = Scheduler(composite=CHILD, remote_trigger=True)
        executor.add_node(child)
        vkc = rclpy.create_node('VKC', namespace=CHILD.namespace)
        executor.add_node(vkc)
        seen_at_tick: list = []
        runtime.bus.carry(TOPIC)  # the parent said so when it bound the child's input
        relation = InputPort(vkc, PortSpec(name='relation', direction='input', msg_type=Float64, type='signal'))
        relation.connect(TOPIC)
        assert not [s for s in vkc.subscriptions if s.topic_name == TOPIC]
        child.tick = lambda t: seen_at_tick.append((t, relation.latest.data))  # what an entity would read
        parent_node = rclpy.create_node('scheduler', namespace='/carry/itasc', context=other)
        theirs.add_node(parent_node)
        publisher = parent_node.create_publisher(Trigger, CHILD.trigger_topic, DATA_QOS)
        assert _spin_until(lambda: publisher.get_subscription_count() > 0, executor, theirs)
        publisher.publish(serialize(trigger_of(3.0, [(TOPIC, Float64Sample(0.75))])))
        assert _spin_until(lambda: seen_at_tick, executor, theirs)
        assert seen_at_tick == [(3.0, 0.75)] and relation.remote == {TOPIC}

"""In-process data flow (itasc_core.communication.ports.LocalBus): an input connected to an output of
its own process gets each sample at the write, with no DDS reader; the bus is the process's (one per
ROS context), so an output of another context is reached over DDS only."""

from __future__ import annotations

import time

import rclpy
from rclpy.context import Context
from std_msgs.msg import Float64

from itasc_core.communication.ports import InputPort, OutputPort, PortSpec
from itasc_core.composition.deployment import Runtime, make_executor
from ros_teardown import destroy_all, two_contexts

TOPIC = '/bus/source/value'


def _spec(direction: str) -> PortSpec:
    return PortSpec(name='value', direction=direction, msg_type=Float64, type='signal', id=TOPIC)


def test_a_colocated_input_gets_each_sample_at_the_write_and_another_context_does_not_link():
    rclpy.init()
    other = Context()
    rclpy.init(context=other)
    executor = make_executor()
    runtime = Runtime(executor=executor, namespace='/bus')
    try:
        node = rclpy.create_node('source', namespace='/bus')
        executor.add_node(node)
        output = OutputPort(node, _spec('output'))
        local = InputPort(node, _spec('input'))
        local.connect(TOPIC)
        stranger_node = rclpy.create_node('stranger', namespace='/bus', context=other)
        stranger = InputPort(stranger_node, _spec('input'))
        stranger.connect(TOPIC)
        assert runtime.bus.lookup(TOPIC) is output
        output.write(Float64(data=1.5))
        assert local.latest is not None and local.latest.data == 1.5  # no spin: handed over in the write
        assert stranger.latest is None
        assert stranger_node.get_subscriptions_info_by_topic(TOPIC) != []  # the stranger reads over DDS
        assert not [s for s in node.subscriptions if s.topic_name == TOPIC]  # the local input does not
        output.destroy()
        assert runtime.bus.lookup(TOPIC) is None
        stranger.disconnect()
        stranger_node.destroy_node()
    finally:
        destroy_all(executor)
        rclpy.try_shutdown(context=other)


def test_a_switched_off_composite_is_sent_nothing_and_gets_the_first_sample_after_it_is_on_again():
    """A Task composite in another process that its parent's Scheduler switched off: its readers do
    not count as listening, so no sample is sent to it; another reader (the recorder, ``ros2 topic
    echo``) still gets them all."""
    with two_contexts('/bus') as (executor, runtime, theirs, other):
        node = rclpy.create_node('Scene', namespace='/bus/itasc')
        executor.add_node(node)
        output = OutputPort(node, _spec('output'))
        task_node = rclpy.create_node('VKC', namespace='/bus/itasc/Retreat', context=other)
        theirs.add_node(task_node)
        task = InputPort(task_node, _spec('input'))
        task.connect(TOPIC)

        def write_for(seconds: float, value: float) -> None:
            end = time.monotonic() + seconds
            while time.monotonic() < end:
                output.write(Float64(data=value))
                executor.spin_once(timeout_sec=0.005)
                theirs.spin_once(timeout_sec=0.005)

        deadline = time.monotonic() + 10
        while task.received == 0 and time.monotonic() < deadline:  # discovery
            write_for(0.05, 1.0)
        assert task.received > 0

        runtime.bus.set_idle('/bus/itasc/Retreat', True)  # its Scheduler item switched off
        write_for(0.3, 1.0)  # what was on the way arrives
        before = task.received
        write_for(1.0, 2.0)
        assert task.received == before

        runtime.bus.set_idle('/bus/itasc/Retreat', False)
        output.write(Float64(data=3.0))  # the first write after it is on again is sent
        end = time.monotonic() + 2
        while task.latest.data != 3.0 and time.monotonic() < end:
            theirs.spin_once(timeout_sec=0.01)
        assert task.latest.data == 3.0

        runtime.bus.set_idle('/bus/itasc/Retreat', True)
        echo_node = rclpy.create_node('echo', namespace='/', context=other)  # a reader outside it
        theirs.add_node(echo_node)
        echo = InputPort(echo_node, _spec('input'))
        echo.connect(TOPIC)
        deadline = time.monotonic() + 10
        while echo.received == 0 and time.monotonic() < deadline:
            write_for(0.05, 4.0)
        assert echo.received > 0 and task.latest.data == 4.0
        echo.disconnect()
        task.disconnect()


def test_a_reader_in_another_process_gets_the_message_of_each_sample_written():
    """An output sends a DDS reader its sample's CDR bytes (no ROS message built in the tick): a
    reader of another context decodes exactly the message the sample stands for, names, stamp,
    numbers and a field a sample holds its own way (``rotation``: None is -1) alike."""
    import numpy as np

    from itasc_core.itasc.entities.messages import FeaturesSample
    from itasc_msgs.msg import Features

    topic = '/bus/itasc/Scene/relation_T'
    spec = PortSpec(name='relation', direction='output', msg_type=Features, type='features', id=topic)
    rclpy.init()
    other = Context()
    rclpy.init(context=other)
    executor, theirs = make_executor(), make_executor(context=other)
    node = rclpy.create_node('Scene', namespace='/bus/itasc')
    try:
        output = OutputPort(node, spec)
        reader_node = rclpy.create_node('echo', namespace='/', context=other)
        theirs.add_node(reader_node)
        received: list[Features] = []
        reader_node.create_subscription(Features, topic, received.append, 10)
        samples = [FeaturesSample(12.000000000499, ('x', 'y', 'z', 'rx', 'ry', 'rz'), ('j1', 'j2', 'j3'),
                                  np.arange(6.0), np.arange(18.0).reshape(6, 3), rotation=3),
                   FeaturesSample(1.25, ('distance',), ('j1', 'j2', 'j3'), np.array([0.5]),
                                  np.array([[1.0, -2.0, 0.25]]))]
        deadline = time.monotonic() + 10
        while not received and time.monotonic() < deadline:  # discovery
            output.write(samples[0])
            theirs.spin_once(timeout_sec=0.05)
        assert received, 'the reader of another context heard nothing'
        for sample in samples:
            output.write(sample)
        expected = [sample.to_message() for sample in samples]
        end = time.monotonic() + 5
        while received[-1] != expected[-1] and time.monotonic() < end:
            theirs.spin_once(timeout_sec=0.05)
        received = received[-2:]  # before them: the writes of the discovery
        assert received == expected
        assert received[1].rotation == -1 and list(received[0].names) == ['x', 'y', 'z', 'rx', 'ry', 'rz']
        output.destroy()
    finally:
        destroy_all(theirs, context=other)
        destroy_all(executor, node)


def test_the_inputs_of_a_composite_share_one_reader_of_a_remote_topic_and_it_outlives_its_first_port():
    """Two Monitors of a composite watching the state of a Task in another process: one DDS reader
    in their process hands every sample to both (each reader takes and converts every sample). When
    the port whose node holds the reader goes (a removed entity), the other's node reads on, and
    once the last port went the process holds no reader of the topic. An input of another composite
    of the process has a reader of its own (a composite switched off does not listen)."""
    with two_contexts('/bus') as (executor, _, theirs, other):
        source = rclpy.create_node('source', namespace='/bus/task', context=other)
        theirs.add_node(source)
        output = OutputPort(source, _spec('output'))
        nodes = [rclpy.create_node(name, namespace=namespace) for name, namespace in
                 (('tracking_error', '/bus/itasc'), ('converged', '/bus/itasc'), ('arrived', '/bus/itasc/child'))]
        for node in nodes:
            executor.add_node(node)
        first, second, elsewhere = (InputPort(node, _spec('input')) for node in nodes)
        for port in (first, second, elsewhere):
            port.connect(TOPIC)

        def readers() -> list[str]:
            return sorted(f'{i.node_namespace}/{i.node_name}' for i in source.get_subscriptions_info_by_topic(TOPIC))

        def send_until(condition, value: float) -> bool:
            deadline = time.monotonic() + 10
            while not condition() and time.monotonic() < deadline:
                output.write(Float64(data=value))
                theirs.spin_once(timeout_sec=0.005)
                executor.spin_once(timeout_sec=0.005)
            return condition()

        assert send_until(lambda: first.latest is not None and second.latest is not None
                          and elsewhere.latest is not None, 1.0)
        assert readers() == ['/bus/itasc/child/arrived', '/bus/itasc/tracking_error']
        assert second.latest is first.latest  # one sample, decoded once, for both
        first.disconnect()  # its node held the reader
        assert send_until(lambda: readers() == ['/bus/itasc/child/arrived', '/bus/itasc/converged'], 1.0)
        assert send_until(lambda: second.latest.data == 2.0, 2.0)
        second.disconnect()
        assert send_until(lambda: readers() == ['/bus/itasc/child/arrived'], 3.0)
        received = second.received
        assert send_until(lambda: elsewhere.latest.data == 4.0, 4.0)
        assert second.received == received

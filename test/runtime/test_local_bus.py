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
from ros_teardown import destroy_all

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
    rclpy.init()
    other = Context()
    rclpy.init(context=other)
    executor, theirs = make_executor(), make_executor(context=other)
    runtime = Runtime(executor=executor, namespace='/bus')
    try:
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
    finally:
        destroy_all(theirs, context=other)
        destroy_all(executor)

"""In-process data flow (itasc_core.communication.ports.LocalBus): an input connected to an output of
its own process gets each sample at the write, with no DDS reader; the bus is the process's (one per
ROS context), so an output of another context is reached over DDS only."""

from __future__ import annotations

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

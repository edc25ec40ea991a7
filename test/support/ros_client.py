"""A ROS 2 client in the test process, as ``ros2 param get`` or ``ros2 service call`` would be:
its own context and node, created for one question and destroyed after it."""

from __future__ import annotations

import time
from contextlib import contextmanager
from typing import Any, Iterator

import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

__all__ = ['ros_node', 'get_parameter', 'call', 'spin_until']


@contextmanager
def ros_node(name: str = 'test_client') -> Iterator[tuple[Node, SingleThreadedExecutor]]:
    context = Context()
    rclpy.init(context=context)
    node = rclpy.create_node(name, context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    try:
        yield node, executor
    finally:
        executor.remove_node(node)
        node.destroy_node()
        executor.shutdown()
        rclpy.try_shutdown(context=context)


def spin_until(executor, condition, timeout: float) -> bool:
    """Spin ``executor`` until ``condition()`` holds; whether it did within ``timeout`` s."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if condition():
            return True
        executor.spin_once(timeout_sec=0.02)
    return condition()


def call(node: Node, executor, srv_type, service: str, request, *, timeout: float = 10.0) -> Any:
    """Call ``service`` once it is there; the response, or AssertionError after ``timeout`` s."""
    client = node.create_client(srv_type, service)
    try:
        deadline = time.monotonic() + timeout
        while not client.service_is_ready():
            assert time.monotonic() < deadline, f'service {service} did not appear within {timeout} s'
            executor.spin_once(timeout_sec=0.05)
        future = client.call_async(request)
        executor.spin_until_future_complete(future, timeout_sec=max(0.1, deadline - time.monotonic()))
        assert future.done(), f'{service} did not answer within {timeout} s'
        return future.result()
    finally:
        node.destroy_client(client)


def get_parameter(node_name: str, parameter: str, *, timeout: float = 10.0) -> Any:
    """The value of ``parameter`` of the running node ``node_name`` (fully qualified), read through
    its ``get_parameters`` service."""
    from rcl_interfaces.srv import GetParameters
    from rclpy.parameter import parameter_value_to_python

    with ros_node() as (node, executor):
        response = call(node, executor, GetParameters, f'{node_name}/get_parameters',
                        GetParameters.Request(names=[parameter]), timeout=timeout)
    assert len(response.values) == 1, response
    return parameter_value_to_python(response.values[0])

"""ROS 2 clients of a test, as ``ros2 param get`` or ``ros2 service call`` would be: a context and
node of the test process created for one question and destroyed after it (``ros_node``), or, for a
request that changes the application, a client process of its own (``call_service``)."""

from __future__ import annotations

import base64
import json
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator

import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

__all__ = ['ros_node', 'get_parameter', 'call', 'call_service', 'call_services', 'spin_until']


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


def call_services(calls: list[tuple[Any, str, Any]], *, timeout: float = 30.0) -> list[Any]:
    """Make the calls ``(service type, service, request)`` in order from a client process of their
    own (``service_call``), each once its service is there; their responses. A request that stops,
    recovers or re-composes the application makes participants come and go while the client ends,
    which a client in the test process would not survive every time (see ``service_call``)."""
    from rclpy.serialization import deserialize_message, serialize_message

    sent = [{'type': _type_name(kind), 'service': service, 'timeout': timeout,
             'request': base64.b64encode(serialize_message(request)).decode()} for kind, service, request in calls]
    script = Path(__file__).with_name('service_call.py')
    try:
        done = subprocess.run([sys.executable, str(script)], input=json.dumps(sent), capture_output=True,
                              text=True, timeout=len(calls) * timeout + 30)
    except subprocess.TimeoutExpired as expired:
        raise AssertionError(f'the client of {[c[1] for c in calls]} did not end: {expired.stderr}') from None
    assert done.returncode == 0, f'the client of {[c[1] for c in calls]} failed: {done.stderr.strip()}'
    return [deserialize_message(base64.b64decode(answer), kind.Response)
            for answer, (kind, _, _) in zip(json.loads(done.stdout), calls)]


def call_service(kind, service: str, request, *, timeout: float = 30.0) -> Any:
    """``ros2 service call <service> <kind> <request>``: the response."""
    (response,) = call_services([(kind, service, request)], timeout=timeout)
    return response


def _type_name(kind) -> str:
    """The service class -> ``pkg/srv/Name``."""
    return f"{kind.__module__.split('.')[0]}/srv/{kind.__name__}"


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

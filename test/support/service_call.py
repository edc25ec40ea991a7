"""A ROS 2 service client in a process of its own, as ``ros2 service call`` is: the test process
hands it the calls (service type, service, serialized request) as JSON on stdin, and reads the
serialized responses as JSON from stdout.

It ends with ``os._exit`` once the answers are out, without deleting its node: a request such as
``~/stop`` or ``~/compose`` makes DDS participants leave or come while the client would delete its
own, and Fast DDS 2.14 can deadlock deleting a participant while it discovers another (see
``ros_teardown``). A process that exits is unaffected; a test process stuck in C would be.
"""

from __future__ import annotations

import base64
import importlib
import json
import os
import sys
import time


def service_type(name: str):
    """``pkg/srv/Name`` -> the service class."""
    package, _, kind = name.split('/')
    return getattr(importlib.import_module(f'{package}.srv'), kind)


def fail(reason: str) -> None:
    sys.stderr.write(reason + '\n')
    sys.stderr.flush()
    os._exit(1)


def main() -> None:
    import rclpy
    from rclpy.serialization import deserialize_message, serialize_message

    calls = json.load(sys.stdin)
    rclpy.init()
    node = rclpy.create_node('service_call')
    answers = []
    for request in calls:
        kind = service_type(request['type'])
        client = node.create_client(kind, request['service'])
        deadline = time.monotonic() + request['timeout']
        while not client.service_is_ready():
            if time.monotonic() > deadline:
                fail(f"service {request['service']} did not appear within {request['timeout']} s")
            rclpy.spin_once(node, timeout_sec=0.05)
        future = client.call_async(deserialize_message(base64.b64decode(request['request']), kind.Request))
        rclpy.spin_until_future_complete(node, future, timeout_sec=max(0.1, deadline - time.monotonic()))
        if not future.done():
            fail(f"{request['service']} did not answer within {request['timeout']} s")
        answers.append(base64.b64encode(serialize_message(future.result())).decode())
    sys.stdout.write(json.dumps(answers))
    sys.stdout.flush()
    os._exit(0)


if __name__ == '__main__':
    main()

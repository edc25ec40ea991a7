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
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.serialization import deserialize_message, serialize_message
    from ros_client import call

    calls = json.load(sys.stdin)
    rclpy.init()
    node = rclpy.create_node('service_call')
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    answers = []
    for request in calls:
        kind = service_type(request['type'])
        try:
            response = call(node, executor, kind, request['service'],
                            deserialize_message(base64.b64decode(request['request']), kind.Request),
                            timeout=request['timeout'])
        except AssertionError as err:
            fail(str(err))
        answers.append(base64.b64encode(serialize_message(response)).decode())
    sys.stdout.write(json.dumps(answers))
    sys.stdout.flush()
    os._exit(0)


if __name__ == '__main__':
    main()

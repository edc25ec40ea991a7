"""Leave nothing of a test's ROS graph behind in the test process.

rmw_fastrtps keeps a context's DDS participant alive as long as one node of the context exists,
even after ``rclpy.shutdown``. Participants left over by earlier tests keep discovering the later
ones inside the same process, and Fast DDS 2.14 can deadlock when a participant is deleted while
it discovers another (seen here: ``DomainParticipant::set_listener`` spinning forever in
``rmw_destroy_node``). So every test destroys every node it created before shutting rclpy down.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import rclpy
from rclpy.context import Context

__all__ = ['destroy_all', 'two_contexts']


def destroy_all(executor, *nodes, context=None) -> None:
    """Destroy every node on ``executor`` and ``nodes``, shut the executor and ``context`` down."""
    on_executor = list(executor.get_nodes())
    for node in on_executor:
        executor.remove_node(node)
    for node in dict.fromkeys([*on_executor, *nodes]):
        try:
            node.destroy_node()
        except Exception:  # noqa: BLE001 - destroyed earlier (a Composer retires its entities)
            pass
    executor.shutdown()
    rclpy.try_shutdown(context=context)


@contextmanager
def two_contexts(namespace: str) -> Iterator[tuple]:
    """Two processes' worth of ROS in this interpreter: ``(executor, runtime, theirs, other)``, the
    default context's executor and process runtime (its bus), and another context with its executor
    (DDS between them, no bus in common); every node of both destroyed at the end."""
    from itasc_core.composition.deployment import Runtime, make_executor
    rclpy.init()
    other = Context()
    rclpy.init(context=other)
    executor, theirs = make_executor(), make_executor(context=other)
    runtime = Runtime(executor=executor, namespace=namespace)
    try:
        yield executor, runtime, theirs, other
    finally:
        destroy_all(theirs, context=other)
        destroy_all(executor)

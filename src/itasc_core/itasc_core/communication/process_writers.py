"""The writers rclpy makes for every node, made once per process (paper §7: communication is the
process's business, not each entity's; issue #9: bring-up of large programs).

rclpy gives every node a ``/rosout`` writer (its log lines) and a ``/parameter_events`` writer
(its parameter changes). A program of 50 Tasks deploys about 450 entity nodes in one process, so
900 such writers, and Fast DDS pairs each new endpoint of a process with every local endpoint of the
other kind (``bench/bench_endpoints.py``): each of these writers made every later reader dearer,
and bring-up grew faster than the number of Tasks. The entities of a process share one of each:

* ``/rosout``: an entity's node is made without a rosout writer, and its logger name is
  registered with rcl as a sublogger of the process node's logger (rcl's rosout sublogger map,
  what rclpy's ``Logger.get_child`` uses): its log lines go out on the process node's writer with
  the same ``name`` as before (``<namespace>.<entity>``, dotted), so ``rqt_console`` and
  ``ros2 topic echo /rosout`` show what they showed.
* ``/parameter_events``: an entity's parameter changes are published by the process's writer. A
  ``ParameterEvent`` names its node in its ``node`` field, which is what ``ros2 param``, rqt and
  rclpy's ``ParameterEventHandler`` read; only the graph no longer lists the entity as a writer of
  the topic.

The process node is named after the composite the process was started for (node ``Reach0`` in
``/app/itasc`` for the composite ``/app/itasc/Reach0``): its logger name (``app.itasc.Reach0``) is
then a prefix of the logger name of every entity of the process. An entity outside that namespace
(none is, in a process deployed by a :class:`~itasc_core.composition.deployment.Runtime`) keeps a
rosout writer of its own.
"""

from __future__ import annotations

import weakref

from rcl_interfaces.msg import ParameterEvent
from rclpy.context import Context
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher
from rclpy.qos import qos_profile_parameter_events

__all__ = ['ProcessWriters', 'PARAMETER_EVENTS', 'process_node', 'serving_nothing']

#: The topic of every node's parameter changes (rclpy's).
PARAMETER_EVENTS = '/parameter_events'


def serving_nothing() -> dict:
    """rclpy ``Node`` options of a node of ours that offers no service: none of rclpy's six
    parameter services, and no ``~/get_type_description`` (it outlives a node destroyed soon after
    it left an EventsExecutor, so an entity removed at run time would stay in the graph; our
    message types are installed wherever our nodes are looked at)."""
    return {'start_parameter_services': False,
            'parameter_overrides': [Parameter('start_type_description_service', value=False)]}


def process_node(executor, *, name: str, namespace: str) -> Node:
    """A node of the process itself (it offers no service), spun by ``executor``."""
    node = Node(name, namespace=namespace, context=executor.context, **serving_nothing())
    executor.add_node(node)
    return node


class ProcessWriters:
    """The ``/rosout`` and ``/parameter_events`` writers of one ROS context (one process)."""

    _of: 'weakref.WeakKeyDictionary[Context, ProcessWriters]' = weakref.WeakKeyDictionary()

    def __init__(self, node: Node) -> None:
        self._node = node
        self._namespace = node.get_fully_qualified_name()
        #: the writer every entity of the process publishes its parameter changes with
        self.parameter_events: Publisher = node.create_publisher(ParameterEvent, PARAMETER_EVENTS,
                                                                 qos_profile_parameter_events)

    @classmethod
    def install(cls, executor, *, namespace: str) -> 'ProcessWriters | None':
        """Give ``executor``'s context its writers, on a node named after ``namespace`` (the
        composite the process was started for), spun by ``executor``. None for the namespace ``/``
        (a node cannot be named after it): each node keeps its own writers."""
        writers = cls._of.get(executor.context)
        if writers is None and namespace.strip('/'):
            parent, _, name = namespace.rstrip('/').rpartition('/')
            writers = cls._of[executor.context] = cls(process_node(executor, name=name, namespace=parent or '/'))
        return writers

    @classmethod
    def of(cls, context: Context) -> 'ProcessWriters | None':
        """The writers of ``context``, if its process installed them."""
        return cls._of.get(context)

    def logs(self, namespace: str) -> bool:
        """Whether the log lines of a node in ``namespace`` go out on the process's writer."""
        return namespace == self._namespace or namespace.startswith(self._namespace + '/')

    def rosout(self, logger_name: str) -> RcutilsLogger:
        """Have the log lines of ``logger_name`` (a node's in :meth:`logs`'s namespaces) published on
        the process's writer for as long as the returned logger is referenced."""
        parent = self._node.get_logger()
        return parent.get_child(logger_name.removeprefix(parent.name + '.'))

"""The visualization process of a running application: ``robot_description``, TF and markers
(see :mod:`.description`, :mod:`.frames`, :mod:`.markers`).

It draws at a display rate (30 Hz), in a process of its own: nothing of it runs in, or competes
for the interpreter with, the control tick (paper §6.2: the Timer's tick computes the Tasks,
nothing else). Started by the bootstrap (``--feed``), it takes the newest samples of the data flow
it draws from (the Driver's joint state, the Tasks' ``Rows/state``, ...) from the bootstrap's
:class:`~.feed.FeedWriter` on its stdin: it adds no DDS reader to a topic the tick publishes,
since every reader costs the tick a send (:mod:`.feed`), and joins DDS when the first feed
arrives, once the application is Running. Run on its own it subscribes to those topics instead.
It publishes

* ``<app>/<robot>/robot_description`` (``std_msgs/String``, transient local), per robot;
* ``/tf_static`` once (fixed joints, object frames, fixed placements) and ``/tf`` at the display
  rate from each robot's newest Driver joint state, stamped with it (as robot_state_publisher);
* ``<app>/markers`` (``visualization_msgs/MarkerArray``) at the display rate.

``/tf`` and the markers are drawn only while someone reads them (RViz, Foxglove, a recording).

    python -m itasc_bringup.visualization.node <app name or model path> [--rate 30] [--feed]
"""

from __future__ import annotations

import argparse
import ctypes
import functools
import os
import signal
import sys
from collections.abc import Callable

import numpy as np
import pinocchio as pin
import rclpy
from geometry_msgs.msg import TransformStamped
from rclpy.context import Context
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import MarkerArray

from itasc_core.communication.qos import DATA_QOS, STATE_QOS
from itasc_core.itasc.coordinates import features_pose
from itasc_msgs.msg import CoordinatorState, Features, TaskState

from ..model.schema import Application
from .description import robot_description
from .feed import FeedReader, display_topics, wait_for_first_frame
from .frames import WORLD, Edge, FrameTree, quaternion_xyzw
from .markers import TaskView, scene_markers

__all__ = ['Visualizer', 'LATCHED_QOS', 'TF_QOS', 'DISPLAY_RATE', 'markers_topic', 'description_topic',
           'joint_states_topic', 'main']

DISPLAY_RATE = 30.0
_PR_SET_PDEATHSIG = 1  # <linux/prctl.h>
#: robot_description and /tf_static: latched, as robot_state_publisher offers them.
LATCHED_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: /tf as tf2_ros' TransformBroadcaster offers it.
TF_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100, reliability=ReliabilityPolicy.RELIABLE,
                    durability=DurabilityPolicy.VOLATILE)


def markers_topic(namespace: str) -> str:
    return f'{namespace}/markers'


def description_topic(namespace: str, robot: str) -> str:
    return f'{namespace}/{robot}/robot_description'


def joint_states_topic(namespace: str, robot: str) -> str:
    return f'{namespace}/{robot}/joint_states'


def transform_msg(edge: Edge, stamp) -> TransformStamped:
    msg = TransformStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = edge.parent
    msg.child_frame_id = edge.child
    t = msg.transform
    t.translation.x, t.translation.y, t.translation.z = map(float, edge.pose.translation)
    t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w = quaternion_xyzw(edge.pose.rotation)
    return msg


def _se3(pose) -> pin.SE3:
    q = pin.Quaternion(pose.orientation.w, pose.orientation.x, pose.orientation.y, pose.orientation.z)
    q.normalize()
    return pin.SE3(q.toRotationMatrix(), np.array([pose.position.x, pose.position.y, pose.position.z]))


class Visualizer(Node):
    """Node ``visualization`` in the application's namespace."""

    def __init__(self, app: Application, *, namespace: str, rate: float = DISPLAY_RATE,
                 feed: int | None = None, context: Context | None = None) -> None:
        super().__init__('visualization', namespace=namespace, context=context)
        self.app = app
        program = f'{namespace}/{app.program.name}'
        descriptions = {r.name: robot_description(r) for r in app.program.robots}
        self.tree = FrameTree.of(app, descriptions)
        self._descriptions = []
        for name, text in descriptions.items():
            publisher = self.create_publisher(String, description_topic(namespace, name), LATCHED_QOS)
            publisher.publish(String(data=text))
            self._descriptions.append(publisher)
        self._static = self.create_publisher(TFMessage, '/tf_static', LATCHED_QOS)
        stamp = self.get_clock().now().to_msg()
        self._static.publish(TFMessage(transforms=[transform_msg(e, stamp) for e in self.tree.static()]))
        self._tf = self.create_publisher(TFMessage, '/tf', TF_QOS,
                                         event_callbacks=PublisherEventCallbacks(matched=self._on_tf_reader))
        self._markers = self.create_publisher(MarkerArray, markers_topic(namespace), DATA_QOS)

        self._joints: dict[str, JointState] = {}
        self._shown: dict[str, object] = {}
        self.views = {t.name: TaskView(t.name) for t in app.program.tasks}
        self._task_seen: dict[str, float] = {}
        for task in app.program.tasks:  # on a change of the Task's state only (latched)
            self.create_subscription(CoordinatorState, f'{program}/{task.name}/state',
                                     functools.partial(self._on_state, task.name), STATE_QOS)
        # the data flow the pictures are drawn from: one handler per topic
        self._handlers: dict[str, Callable] = {}
        topics = display_topics(app, namespace)
        for robot in app.program.robots:
            self._handlers[f'{namespace}/Driver_{robot.name}/joint_state'] = \
                lambda msg, r=robot.name: self._joints.__setitem__(r, msg)
        for sensor in app.sensors:
            self._handlers[f'{namespace}/Sensor_{sensor.object}/pose'] = \
                lambda msg, o=sensor.object: self._set_object(o, _se3(msg.pose))
        for task in app.program.tasks:
            self._handlers[f'{program}/{task.name}/Rows/state'] = self._on_task
            self._handlers[f'{program}/Scene/relation_{task.name}'] = lambda msg, t=task: self._on_relation(t, msg)
        self._handlers = {topic: self._handlers[topic] for topic in topics}
        self._feed = FeedReader(feed, topics) if feed is not None else None
        if self._feed is None:  # on its own: subscribed (each reader costs the tick its publish)
            for topic, msg_type in topics.items():
                self.create_subscription(msg_type, topic, self._handlers[topic], DATA_QOS)
        self._timer = self.create_timer(1.0 / rate, self._display)

    def _on_tf_reader(self, status) -> None:
        """A reader of ``/tf`` joined (a recorder, RViz): the next drawing sends it every robot's
        transforms, however long the robots have stood still. ``/tf`` is volatile and sent on a
        change of a joint state only (tf2 takes a repeated stamp for an error), so a reader matched
        after the last change (discovery is late on a loaded machine, or the run has ended) would
        otherwise never learn where the robots are."""
        if status.current_count_change > 0:
            self._shown.clear()

    def _set_object(self, name: str, pose: pin.SE3) -> None:
        self.tree.objects[name] = pose

    def _on_state(self, task: str, msg: CoordinatorState) -> None:
        self.views[task].running_state = msg.state.removeprefix('Active.Run.').removeprefix('Active.')

    def _on_task(self, msg: TaskState) -> None:
        view = self.views.get(msg.task)
        if view is not None:
            view.active, view.error_norm = bool(msg.active), float(msg.error_norm)
            self._task_seen[msg.task] = self.get_clock().now().nanoseconds * 1e-9

    def _on_relation(self, task, msg: Features) -> None:
        value = np.asarray(msg.value, dtype=float)
        relative = features_pose(value, coordinates='xyz_log3')
        o1, o2 = task.chain['o1'], task.chain['o2']
        pose = self.tree.object_pose_from(o1, o2, relative)
        if pose is not None:
            self._set_object(o1.partition('/')[0], pose)

    def _display(self) -> None:
        if self._feed is not None:
            for topic, msg in self._feed.read():
                self._handlers[topic](msg)
        now = self.get_clock().now().nanoseconds * 1e-9
        for task, seen in self._task_seen.items():  # a Task that stopped reporting is off
            if now - seen > 0.5:
                self.views[task].active = False
        # drawn for readers only: building the markers and TF messages took this process 11-28 %
        # of a core at 30 Hz, which a control process on the same two cores missed when nobody
        # looked (no RViz, Foxglove or recording). A reader that joins gets the next drawing.
        tf_read, markers_read = self._tf.get_subscription_count() > 0, self._markers.get_subscription_count() > 0
        if not (tf_read or markers_read):
            return
        transforms, stamp = [], None
        for name, msg in self._joints.items():
            stamp = msg.header.stamp
            if not tf_read or self._shown.get(name) is msg:
                continue
            self._shown[name] = msg
            edges = self.tree.robots[name].moving(msg.name, msg.position)
            transforms += [transform_msg(e, msg.header.stamp) for e in edges]
        if stamp is None:
            return  # nothing to draw before the first joint state
        if tf_read:
            moving = [Edge(WORLD, o.name, self.tree.objects[o.name]) for o in self.app.program.objects
                      if (o.motion or o.name in {s.object for s in self.app.sensors})
                      and self.tree.objects[o.name] is not None]
            transforms += [transform_msg(e, stamp) for e in moving]
        if transforms:
            self._tf.publish(TFMessage(transforms=transforms))
        if markers_read:
            self._markers.publish(scene_markers(self.app, self.tree, self.views, stamp))


def _follows(parent: int) -> bool:
    """SIGTERM to this process when ``parent`` ends (Linux: PR_SET_PDEATHSIG); False if it ended
    already (this process was handed to another)."""
    ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)
    return os.getppid() == parent


def main(argv: list[str] | None = None) -> int:
    from itasc_core.communication.dds import configure_dds
    from itasc_core.composition.loader import ModelError

    from ..apps import resolve_app
    from ..model import load_application

    parser = argparse.ArgumentParser(prog='visualization', description='robot_description, TF and markers '
                                     'of a running iTaSC application.')
    parser.add_argument('app', help='application name or model path')
    parser.add_argument('--rate', type=float, default=DISPLAY_RATE, help='display rate (Hz)')
    parser.add_argument('--feed', action='store_true',
                        help='take the data flow from the bootstrap on stdin (see .feed) instead of subscribing')
    parser.add_argument('--parent', type=int, metavar='PID',
                        help='end with this process, however it ends (the bootstrap that started this one)')
    args = parser.parse_args(argv)
    if args.parent is not None and not _follows(args.parent):
        return 0
    try:
        app = load_application(resolve_app(args.app))
    except ModelError as err:
        print(f'error: {err}', file=sys.stderr)
        return 2
    # Python's own handlers, not rclpy's: rclpy's shut the context down under a running timer
    # callback, whose publish then fails with a traceback; a KeyboardInterrupt ends spin cleanly.
    signal.signal(signal.SIGTERM, signal.default_int_handler)
    if args.feed:
        try:
            wait_for_first_frame(sys.stdin.fileno())  # the application is Running: join DDS (see .feed)
        except KeyboardInterrupt:
            return 0
    configure_dds()
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = None
    try:
        node = Visualizer(app, namespace=f'/{app.name}', rate=args.rate,
                          feed=sys.stdin.fileno() if args.feed else None)
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())

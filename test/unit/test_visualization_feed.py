"""The display feed (itasc_bringup.visualization.feed, issue #13): the bootstrap hands the newest
samples of its output ports to the visualization process down a pipe, at the display rate, never
blocking and never adding a DDS reader to a topic the tick publishes."""

import contextlib
import os

import pytest

from sensor_msgs.msg import JointState

from itasc_bringup.visualization.feed import FeedReader, FeedWriter, LatestSamples
from itasc_core.communication.ports import LocalBus
from itasc_msgs.msg import TaskState

JOINTS = '/app/Driver_panda/joint_state'
ROWS = '/app/itasc/T/Rows/state'
TOPICS = {JOINTS: JointState, ROWS: TaskState}


class _Context:
    """The ROS context of the node (its process's LocalBus is keyed by it)."""


class _Node:
    """What the feed uses of a node: timers and the graph (no publisher anywhere else)."""

    def __init__(self):
        self.subscriptions = []
        self.context = _Context()

    def create_timer(self, period, callback):
        return callback

    def destroy_timer(self, timer):
        pass

    def count_publishers(self, topic):
        return 0

    def create_subscription(self, *args):
        self.subscriptions.append(args)


class _Port:
    """An output port as LocalBus knows it: its topic and its newest sample."""

    def __init__(self, topic):
        self.topic = topic
        self.last = None


def _joints(i: int, n: int = 7) -> JointState:
    msg = JointState(name=[f'joint{k}' for k in range(n)], position=[float(i)] * n)
    msg.header.stamp.sec = i
    return msg


@pytest.fixture
def feed():
    """A node, the output ports of TOPICS in this process, and a pipe (read fd, write fd)."""
    ports = {topic: _Port(topic) for topic in TOPICS}
    node = _Node()
    bus = LocalBus.of(node.context)
    for port in ports.values():
        bus.register(port)
    fds = os.pipe()
    yield node, ports, fds
    for port in ports.values():
        bus.unregister(port)
    for fd in fds:
        with contextlib.suppress(OSError):  # a test may have closed it
            os.close(fd)


def test_the_newest_samples_arrive_once_each_without_a_subscription(feed):
    node, ports, (read_fd, write_fd) = feed
    writer = FeedWriter(node, LatestSamples(node, TOPICS), write_fd, rate=30.0)
    reader = FeedReader(read_fd, TOPICS)
    writer.send()
    assert reader.read() == [] and writer.frames == 0  # nothing written yet
    ports[ROWS].last = TaskState(task='T', error_norm=0.9)
    writer.send()
    assert reader.read() == [] and writer.frames == 0  # not started: the display waits for Running
    writer.start()  # the first frame goes at once
    assert writer.frames == 1 and [topic for topic, _ in reader.read()] == [ROWS]
    writer.send()
    assert reader.read() == [] and writer.frames == 1  # nothing new
    for i in range(3):  # ticks between two display cycles: only the newest goes
        ports[JOINTS].last = _joints(i)
    ports[ROWS].last = TaskState(task='T', error_norm=0.5, active=True)
    writer.send()
    got = dict(reader.read())
    assert got[JOINTS].header.stamp.sec == 2 and list(got[JOINTS].position) == [2.0] * 7
    assert got[ROWS].task == 'T' and got[ROWS].error_norm == 0.5 and got[ROWS].active
    ports[JOINTS].last = _joints(3)
    writer.send()
    assert [topic for topic, _ in reader.read()] == [JOINTS]  # the Task's state did not change
    writer.send()
    assert reader.read() == []
    assert node.subscriptions == []


def test_a_full_pipe_loses_frames_never_blocks_nor_corrupts_them(feed):
    node, ports, (read_fd, write_fd) = feed
    writer = FeedWriter(node, LatestSamples(node, TOPICS), write_fd, rate=30.0)
    reader = FeedReader(read_fd, TOPICS)
    writer.start()
    i = 0
    while writer.dropped < 3:  # nobody reads: the pipe fills up, frames are dropped
        i += 1
        ports[JOINTS].last = _joints(i, n=300)  # frames of ~10 kB: partial writes happen
        writer.send()
    received = [msg for _, msg in reader.read()]
    stamps = [msg.header.stamp.sec for msg in received]
    assert stamps and stamps == sorted(set(stamps)) and len(stamps) < i  # in order, some lost
    assert all(list(msg.position) == [float(msg.header.stamp.sec)] * 300 for msg in received)  # whole
    writer.send()  # the rest of a frame cut by the full pipe, then the newest again
    ports[JOINTS].last = _joints(i + 1, n=300)
    writer.send()
    writer.send()
    later = [msg for _, msg in reader.read()]
    assert later[-1].header.stamp.sec == i + 1 and len(later[-1].position) == 300


def test_a_gone_reader_ends_the_feed_and_a_gone_writer_is_seen(feed):
    node, ports, (read_fd, write_fd) = feed
    reader = FeedReader(read_fd, TOPICS)
    writer = FeedWriter(node, LatestSamples(node, TOPICS), write_fd, rate=30.0)
    writer.start()
    os.close(read_fd)
    ports[JOINTS].last = _joints(1)
    writer.send()  # EPIPE: the visualization process is gone
    writer.send()
    read_fd, other = os.pipe()
    reader = FeedReader(read_fd, TOPICS)
    os.close(other)
    try:
        assert reader.read() == [] and reader.closed
    finally:
        os.close(read_fd)


def test_the_display_takes_a_remote_topic_from_the_consoles_reader_instead_of_reading_it_again():
    """A Task's state published in another process (here another ROS context: another LocalBus,
    real DDS between them) is read by the console's observer; the display's LatestSamples takes the
    newest from that reader: the process holds one reader of the topic, not two that would each
    take and convert every sample at the tick rate, and the display still sees the newest state."""
    import time

    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor

    from itasc_bringup.console.watch import WATCH_QOS
    from itasc_bringup.observe import Observer

    here, there = Context(), Context()
    rclpy.init(context=here)
    rclpy.init(context=there)
    node, task = rclpy.create_node('bootstrap', context=here), rclpy.create_node('task', context=there)
    try:
        publisher = task.create_publisher(TaskState, ROWS, 10)
        executor = SingleThreadedExecutor(context=here)
        executor.add_node(node)

        def spin_until(condition) -> bool:
            deadline = time.monotonic() + 10.0
            while not condition() and time.monotonic() < deadline:
                executor.spin_once(timeout_sec=0.02)
            return condition()

        seen: list = []
        observer = Observer(node)  # the console's: every sample
        observer.samples(ROWS, TaskState, lambda _, sample: seen.append(sample), qos=WATCH_QOS)
        latest = LatestSamples(node, {ROWS: TaskState}, observers=[observer])
        assert spin_until(lambda: node.count_publishers(ROWS) > 0 and publisher.get_subscription_count() > 0)
        assert latest.get(ROWS) is None  # nothing sent yet
        readers = [info for info in node.get_subscriptions_info_by_topic(ROWS) if info.node_name == 'bootstrap']
        assert len(readers) == 1, readers
        publisher.publish(TaskState(task='T', error_norm=0.5))
        assert spin_until(lambda: latest.get(ROWS) is not None)
        assert latest.get(ROWS).error_norm == 0.5 and [s.error_norm for s in seen] == [0.5]
    finally:
        node.destroy_node()
        task.destroy_node()
        rclpy.try_shutdown(context=here)
        rclpy.try_shutdown(context=there)

"""How the display side gets the data flow without costing the control loop anything per tick.

Measured (issue #13, ``bench/bench_visualization.py``): every DDS reader of a data-flow topic makes
the tick pay for that topic's publish. An output port publishes on DDS only while someone outside
the process listens (:class:`itasc_core.communication.ports.OutputPort`), and Fast DDS sends each
sample in the publishing thread, in the tick (a UDP ``sendto`` per reader, and a wake-up of its
event thread for the reliable protocol). With the visualization process subscribed to the Driver's
joint state and every Task's ``Rows/state``, and the diagnostics to the Solver status, those five
publishes took 0.2-0.6 ms each on a loaded two-core machine, and the tick median of
``approach_object`` doubled (2.5 ms -> 5.2 ms). A reader on a topic the tick publishes anyway
costs the same: one on the Driver's ``<robot>/joint_states`` made that publish 3-4 times dearer.

So nothing of the display subscribes to a topic the tick writes. Every output port already keeps
its newest sample (``OutputPort.last``, no work added to the tick); :class:`LatestSamples` looks
those up in this process's :class:`~itasc_core.communication.ports.LocalBus` when it wants them,
at its own rate. A topic whose publisher lives in another process (``--deploy per-composite``)
is read over DDS instead, by one reader in the bootstrap, as the visualization process read it
before: that process's ticks still pay one send per sample for it.

:class:`FeedWriter` (in the bootstrap, on its node, between ticks) sends the newest samples of the
display's topics at the display rate, CDR-serialised, down a pipe to the visualization process it
started; :class:`FeedReader` (in that process) takes them without blocking. A pipe, not a topic:
nothing else listens, nothing is discovered, and a stalled reader only loses frames (the writer
never blocks).

The first frame goes once the application is Running (:meth:`FeedWriter.start`), and the
visualization process joins DDS only when it arrives (:func:`wait_for_first_frame`): a participant
present during the bring-up takes in the discovery of every endpoint the bring-up makes, each
announcement carrying the whole graph of its process, and a program of 50 Tasks came up
20-30 % later with the display's participant there (2-core VM).
"""

from __future__ import annotations

import functools
import os
import pickle
import select
import struct
from collections.abc import Iterable, Iterator
from typing import Any

from geometry_msgs.msg import PoseStamped
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState

from itasc_core.communication.cdr import serialize
from itasc_core.communication.ports import LocalBus
from itasc_msgs.msg import Features, TaskState

from ..observe import Observer

__all__ = ['LatestSamples', 'FeedWriter', 'FeedReader', 'display_topics', 'wait_for_first_frame', 'LATEST_QOS']

#: A reader that wants the newest sample only (a remote output, read by the display side).
LATEST_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE)

_LENGTH = struct.Struct('<I')


def display_topics(app, namespace: str) -> dict[str, type]:
    """The data-flow topics TF and the markers are drawn from (topic -> message type): each
    robot's Driver joint state, each sensed object's pose, each Task's ``Rows/state`` and, for a
    Task whose o1 is a moving object, its Scene relation."""
    program = f'{namespace}/{app.program.name}'
    topics: dict[str, type] = {f'{namespace}/Driver_{r.name}/joint_state': JointState for r in app.program.robots}
    topics |= {f'{namespace}/Sensor_{s.object}/pose': PoseStamped for s in app.sensors}
    moving = {o.name for o in app.program.objects if o.motion}
    for task in app.program.tasks:
        topics[f'{program}/{task.name}/Rows/state'] = TaskState
        if task.kind.reads == 'relation' and task.chain['o1'].partition('/')[0] in moving:
            topics[f'{program}/Scene/relation_{task.name}'] = Features
    return topics


class LatestSamples:
    """The newest sample of each of ``topics`` (topic -> message type), taken when asked for:
    from the output port in this process (no DDS, nothing done per tick), else, once a publisher
    in another process shows up, from what one of ``observers`` already reads of it over DDS
    (:meth:`~itasc_bringup.observe.Observer.share`: the console's reader of a Task's state), or
    from a subscription of its own that keeps the newest sample only. A remote topic read twice
    in one process is taken and converted twice per sample, at the tick rate: with ``--deploy
    per-composite`` at 500 Hz the bootstrap read each Task's state and the Solver status twice
    (2-core VM: 445-462 Hz achieved with the display's readers, 461-467 Hz without any; sharing
    them, three paired runs, 433-458 Hz before, 446-461 Hz after: within this machine's noise)."""

    def __init__(self, node: Node, topics: dict[str, type], *, observers: Iterable[Observer] = ()) -> None:
        self._node = node
        self._types = dict(topics)
        self._observers = list(observers)
        self._remote: dict[str, Any] = {}  # topic -> newest sample or message of a remote publisher
        self._subscriptions: list = []
        self._bus = LocalBus.of(node.context)

    def _resolve(self, topic: str) -> None:
        """Start taking ``topic`` from its publisher in another process, if it has one."""
        if self._node.count_publishers(topic) == 0:
            return
        self._remote[topic] = None
        if not any(observer.share(topic, self._keep) for observer in self._observers):
            self._subscriptions.append(self._node.create_subscription(
                self._types[topic], topic, functools.partial(self._keep, topic), LATEST_QOS))

    def _keep(self, topic: str, msg: Any) -> None:
        self._remote[topic] = msg

    def get(self, topic: str) -> Any | None:
        """The newest sample on ``topic`` (a port's sample, or what a remote publisher sent), None
        before the first (or before its output exists)."""
        port = self._bus.lookup(topic)  # also the output that replaced a re-composed one
        if port is not None:
            return port.last
        if topic not in self._remote:
            self._resolve(topic)
        return self._remote.get(topic)

    def items(self) -> Iterator[tuple[str, Any]]:
        for topic in self._types:
            sample = self.get(topic)
            if sample is not None:
                yield topic, sample


class FeedWriter:
    """Sends the newest display samples of ``samples`` down the pipe ``fd`` at ``rate`` Hz, from a
    timer of ``node`` (between two ticks: it never runs inside one), once :meth:`start` was
    called. A sample is sent once; a frame the pipe cannot take now is dropped, the writer never
    blocks."""

    def __init__(self, node: Node, samples: LatestSamples, fd: int, *, rate: float) -> None:
        self._samples = samples
        self._fd = fd
        os.set_blocking(fd, False)
        self._sent: dict[str, Any] = {}
        self._pending = b''
        self.frames = self.dropped = 0
        self.started = False
        self._node = node
        self._timer = node.create_timer(1.0 / rate, self.send)

    def start(self) -> None:
        """Send from now on; the first frame goes at once, with nothing in it if there is no
        sample yet."""
        if not self.started:
            self.started = True
            self.send(always=True)

    def send(self, *, always: bool = False) -> None:
        if self._fd < 0 or not self.started:
            return
        if self._pending:  # the rest of a frame the pipe took only part of
            self._pending = self._write(self._pending)
            if self._pending:
                self.dropped += 1
                return
        changed = {topic: msg for topic, msg in self._samples.items() if self._sent.get(topic) is not msg}
        if not changed and not always:
            return
        payload = pickle.dumps({topic: serialize(msg) for topic, msg in changed.items()},
                               protocol=pickle.HIGHEST_PROTOCOL)
        frame = _LENGTH.pack(len(payload)) + payload
        rest = self._write(frame)
        if rest is frame:  # nothing went: dropped whole, sent again next time
            self.dropped += 1
            return
        self._pending = rest
        self.frames += 1
        self._sent.update(changed)

    def _write(self, data: bytes) -> bytes:
        """Writes what the pipe takes now; returns the rest (``data`` itself when nothing went)."""
        if self._fd < 0:
            return b''
        try:
            written = os.write(self._fd, data)
        except BlockingIOError:
            return data
        except OSError:  # the visualization process is gone (EPIPE)
            self.close()
            return b''
        return data if written == 0 else data[written:]

    def close(self) -> None:
        """No more frames; the pipe is its owner's to close."""
        if self._fd >= 0:
            self._fd = -1
            self._node.destroy_timer(self._timer)  # a no-op once the node is destroyed


def wait_for_first_frame(fd: int) -> None:
    """Block until :class:`FeedWriter` sent its first frame on ``fd`` (or closed the pipe)."""
    select.select([fd], [], [])


class FeedReader:
    """Takes the frames :class:`FeedWriter` sent on ``fd`` without blocking."""

    def __init__(self, fd: int, topics: dict[str, type]) -> None:
        self._fd = fd
        self._types = topics
        os.set_blocking(fd, False)
        self._buffer = bytearray()
        self.closed = False

    def read(self) -> Iterable[tuple[str, Any]]:
        """The samples received since the last call, oldest first (topic, message)."""
        while not self.closed:
            try:
                chunk = os.read(self._fd, 1 << 16)
            except BlockingIOError:
                break
            if not chunk:
                self.closed = True  # the bootstrap is gone
                break
            self._buffer += chunk
        out = []
        while len(self._buffer) >= _LENGTH.size:
            (size,) = _LENGTH.unpack_from(self._buffer)
            if len(self._buffer) < _LENGTH.size + size:
                break
            frame = pickle.loads(self._buffer[_LENGTH.size:_LENGTH.size + size])
            del self._buffer[:_LENGTH.size + size]
            out += [(topic, deserialize_message(data, self._types[topic])) for topic, data in frame.items()
                    if topic in self._types]
        return out

"""The samples of a process's outputs streamed to a recording's writer process (issue #9: recording
off the control path; paper §6.1: the data flow of every composite observable, and recorded, in
whichever process it runs).

A recording (``bootstrap --record``) is written by a process of its own (``itasc_bringup.recording.
writer``). The bootstrap's recorder hands it the samples of the bootstrap's own outputs (tapped in
the tick, encoded between ticks) and whatever it reads over DDS. With ``--deploy per-composite``
that was every data-flow topic of the composite processes: each sample built into its ROS message
and sent once more by the composite's process (even for a topic nothing else reads), received over
UDP by the bootstrap's process and handed on by a Python callback on the thread that ticks the
root. ``approach_object`` per composite at 500 Hz with ``--record``: the root's Timer at 428-437 Hz,
the Solver stepped at 251-253 Hz (495 Hz without ``--record``).

So a composite process of this machine records its own outputs: started with the recording's
address (``--record-to``, :class:`~itasc_core.composition.deployment.Runtime`), it runs a
:class:`SampleStream`, which taps every output of the process under the recording's prefix as the
bootstrap taps its own (:meth:`~.ports.OutputPort.tap`: the tick only hands the sample over), turns
the samples into CDR bytes between ticks (:mod:`.cdr`) and sends them down a Unix socket to the
writer process, which writes them next to what the bootstrap sends and tells the bootstrap which
topics come this way (its recorder then reads none of them over DDS). A process on another machine
cannot reach the socket; its outputs are still read over DDS.

The frames, on the bootstrap's pipe and on every socket alike: a header ``<BI`` (kind, payload
length), then the payload: ``TOPIC`` (pickled ``(key, topic, type_name, offered QoS profiles as
rosbag2 writes them)``, :func:`~.qos.qos_profiles`), ``MESSAGES`` (records ``<IqqI``: key, log
time, publish time, length, then the CDR bytes), ``FLUSH``, ``CLOSE`` (the pipe only: a socket's
end is its stream's end). :class:`FrameSender` writes them without ever blocking its caller: what
the pipe or socket cannot take now waits for the next call, so a stalled writer never stalls a
control loop, and nothing is lost until the sender closes.
"""

from __future__ import annotations

import collections
import os
import pickle
import select
import socket
import struct
import time
from collections.abc import Callable, Iterable
from typing import Any

from .cdr import serialize_all
from .ports import LocalBus, OutputPort
from .qos import DATA_QOS, qos_profiles

__all__ = ['FrameSender', 'SampleStream', 'TOPIC', 'MESSAGES', 'FLUSH', 'CLOSE', 'FRAME', 'RECORD', 'BATCH',
           'SEND_PERIOD', 'abstract_address', 'under']

TOPIC, MESSAGES, FLUSH, CLOSE = 1, 2, 3, 4
FRAME = struct.Struct('<BI')
RECORD = struct.Struct('<IqqI')
#: Messages are sent once this many bytes are waiting (or on flush).
BATCH = 1 << 16
#: A stream sends what waits at least this often [s], however little: what a process killed
#: later held back is lost, and the writer flushes the bag every second for ``mcap recover``.
SEND_PERIOD = 0.1


def abstract_address(name: str) -> str:
    """The address of the abstract Unix socket ``name`` (Linux: no file to leave behind)."""
    return '\0' + name


def under(topic: str, prefix: str) -> bool:
    """Whether ``topic`` is ``prefix`` or under it."""
    prefix = '/' + prefix.strip('/')
    return prefix == '/' or topic == prefix or topic.startswith(prefix + '/')


class FrameSender:
    """Frames to a non-blocking file descriptor (a pipe, a socket), never blocking the caller. Not
    thread-safe: one caller at a time."""

    def __init__(self, fd: int) -> None:
        self._fd = fd
        os.set_blocking(fd, False)
        #: frames not (wholly) sent yet, the first maybe in part
        self._unsent: collections.deque[memoryview] = collections.deque()
        self._pending = bytearray()
        self._keys = 0
        #: the reader is gone: nothing more can be sent
        self.broken = False

    def add_topic(self, topic: str, type_name: str, *, profiles: list[dict[str, Any]]) -> int:
        """Announce ``topic`` (its offered QoS ``profiles`` as :func:`~.qos.qos_profiles` gives them);
        returns its key."""
        self._keys += 1
        self._flush_pending()
        self._send(TOPIC, pickle.dumps((self._keys, topic, type_name, profiles)))
        return self._keys

    def write_all(self, records: Iterable[tuple[int, bytes, int, int]]) -> None:
        """Send each ``(key, data, time_ns, publish_time_ns)``, in batches of :data:`BATCH` bytes."""
        pending, pack = self._pending, RECORD.pack
        for key, data, time_ns, publish_time_ns in records:
            pending += pack(key, time_ns, publish_time_ns, len(data))
            pending += data
        if len(pending) >= BATCH:
            self._flush_pending()
        elif self._unsent:
            self._send_what_fits()

    def send(self, kind: int) -> None:
        """Send what waits, then an empty frame ``kind`` (``FLUSH``, ``CLOSE``)."""
        self._flush_pending()
        self._send(kind, b'')

    def send_waiting(self) -> None:
        """Send what waits (as much as fits now)."""
        self._flush_pending()
        self._send_what_fits()

    def finish(self, *, deadline: float) -> bool:
        """Send what waits, waiting for the reader until ``deadline`` (``time.monotonic()``) at
        most; whether all of it was sent."""
        self._flush_pending()
        while self._unsent and not self.broken and time.monotonic() < deadline:
            select.select([], [self._fd], [], max(0.0, deadline - time.monotonic()))
            self._send_what_fits()
        return not self._unsent and not self.broken

    @property
    def unsent(self) -> int:
        """Bytes handed over that were not sent yet."""
        return len(self._pending) + sum(len(frame) for frame in self._unsent)

    def _flush_pending(self) -> None:
        if self._pending:
            self._send(MESSAGES, bytes(self._pending))
            self._pending.clear()

    def _send(self, kind: int, payload: bytes) -> None:
        self._unsent.append(memoryview(FRAME.pack(kind, len(payload)) + payload))
        self._send_what_fits()

    def _send_what_fits(self) -> None:
        unsent = self._unsent
        while unsent and not self.broken:
            try:
                written = os.write(self._fd, unsent[0])
            except BlockingIOError:  # full: the next call goes on
                return
            except InterruptedError:
                continue
            except (BrokenPipeError, ConnectionResetError):  # the reader is gone
                self.broken = True
                unsent.clear()
                return
            if written == len(unsent[0]):
                unsent.popleft()
            else:
                unsent[0] = unsent[0][written:]


class SampleStream:
    """Every sample of this process's outputs under ``prefix`` (those there now and those to come),
    sent to the writer process listening at ``address`` (see the module docstring). Call
    :meth:`drain` between ticks and :meth:`close` when the process ends."""

    def __init__(self, bus: LocalBus, *, address: str, prefix: str,
                 on_broken: Callable[[], None] | None = None) -> None:
        """``on_broken()``: told once if the writer process goes away (nothing more is recorded
        from here). Raises :class:`OSError` when ``address`` cannot be reached."""
        self._socket = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            self._socket.connect(address)
        except OSError:
            self._socket.close()
            raise
        self._sender = FrameSender(self._socket.fileno())
        self._bus = bus
        self._prefix = prefix
        self._on_broken = on_broken
        #: topic -> (its output, the tap handed to it)
        self._tapped: dict[str, tuple[OutputPort, Callable[[str, Any], None]]] = {}
        self._keys: dict[str, int] = {}
        #: tapped samples not sent yet: (key, tapped at [ns], sample)
        self._pending: list[tuple[int, int, Any]] = []
        self._closed = False
        self._sent_at = time.monotonic()
        self._unwatch = bus.watch(self._appeared)
        for port in bus.outputs():
            self._appeared(port)

    @property
    def topics(self) -> set[str]:
        """The topics this stream records."""
        return set(self._keys)

    def _appeared(self, port: OutputPort) -> None:
        topic = port.topic
        if self._closed or not under(topic, self._prefix):
            return
        previous = self._tapped.get(topic)
        if previous is not None:
            if previous[0] is port:
                return
            previous[0].untap(previous[1])  # re-composed: a new output on the same topic
        key = self._keys.get(topic)
        if key is None:
            key = self._keys[topic] = self._sender.add_topic(topic, port.spec.msg_type_name,
                                                             profiles=qos_profiles([DATA_QOS]))
        pending = self._pending  # the one list, emptied in place by drain()

        def tap(_: str, sample: Any) -> None:
            pending.append((key, time.time_ns(), sample))
        port.tap(tap)
        self._tapped[topic] = (port, tap)

    def drain(self) -> None:
        """Send the samples tapped since the last call, as CDR bytes (a few microseconds each)."""
        if self._pending:
            pending = self._pending[:]
            del self._pending[:]
            encoded = serialize_all(sample for *_, sample in pending)
            self._sender.write_all([(key, data, tapped_at, tapped_at)
                                    for (key, tapped_at, _), data in zip(pending, encoded)])
        if time.monotonic() - self._sent_at >= SEND_PERIOD:
            self._sent_at = time.monotonic()
            self._sender.send_waiting()
        self._check()

    def close(self, *, timeout: float = 2.0) -> None:
        """Send what was tapped, waiting for the writer ``timeout`` seconds at most, and end the
        stream. Idempotent."""
        if self._closed:
            return
        self.drain()
        self._closed = True
        self._unwatch()
        for topic, (port, tap) in self._tapped.items():
            port.untap(tap)
            current = self._bus.lookup(topic)  # one that took the output over (its taps too)
            if current is not None:
                current.untap(tap)
        self._tapped.clear()
        self._sender.finish(deadline=time.monotonic() + timeout)
        self._check()
        self._socket.close()

    def _check(self) -> None:
        if self._sender.broken and self._on_broken is not None:
            on_broken, self._on_broken = self._on_broken, None
            on_broken()

"""The process that writes a recording (issue #9: recording off the control path).

Writing MCAP (chunking, zstd compression, the file) takes a good share of a core when every
data-flow topic is recorded at 1 kHz. The recorder (:mod:`.recorder`) hands each message's CDR
bytes to :class:`BagProcess`, which sends them in batches down a pipe to a process running
:func:`main`: that process owns the bag (:class:`~.bag.BagWriter`), flushes it every second and
finishes it (summary, footer, ``metadata.yaml``) when told to close, or when the pipe ends because
the recording process died, however it died. It runs in a session of its own, so that a
terminal's Ctrl-C reaches only the application, which then closes the recording in order.

The caller's thread writes to the pipe itself, without blocking: what the pipe cannot take now
waits for the next call (a stalled writer never stalls the control loop, and nothing is lost
until the recording closes). No thread of ours sends: a thread that wakes up to send takes the
interpreter from the control loop in the middle of a tick (Python's switch interval, 0.5 ms at
1 kHz), and each such hand-over costs the tick more than the write. ``approach_object`` at 1 kHz
``--record``, three alternating pairs: tick p50 618/604/656 us with a sending thread woken every
64 KiB, 535/542/528 us when it was woken every MiB.

Nor does the writer process wait in a read of the pipe: a reader blocked there is woken by the
write itself, in the caller's thread (the kernel wakes it and may hand it the caller's core). It
takes what the pipe holds every :data:`POLL` seconds instead. ``approach_object`` at 1 kHz
``--record``, two runs each, the control thread's writes of a batch: p50 47-53 -> 27-32 us, p99
328-346 -> 106-175 us, the longest 1.3-2.7 -> 0.3-0.45 ms.

Frames on the pipe: a header ``<BI`` (kind, payload length), then the payload: ``TOPIC`` (pickled
``(key, topic, type_name, qos profiles as rosbag2 writes them)``), ``MESSAGES`` (records ``<IqqI``
key, log time, publish time, length, then the CDR bytes), ``FLUSH``, ``CLOSE``.
"""

from __future__ import annotations

import argparse
import collections
import fcntl
import os
import pickle
import select
import signal
import struct
import subprocess
import sys
import time
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

__all__ = ['BagProcess', 'main']

TOPIC, MESSAGES, FLUSH, CLOSE = 1, 2, 3, 4
_FRAME = struct.Struct('<BI')
_RECORD = struct.Struct('<IqqI')
#: Messages are sent once this many bytes are waiting (or on flush).
BATCH = 1 << 16
#: The pipe's size asked for [bytes] (Linux allows up to /proc/sys/fs/pipe-max-size, 1 MiB by default).
PIPE_SIZE = 1 << 20
#: The writer flushes the file at least this often [s] (``mcap recover`` salvages what was flushed).
FLUSH_PERIOD = 1.0
#: The writer takes what the pipe holds this often [s].
POLL = 0.01
#: The writer process's program (not ``-m``: the package imports this module before runpy would run it).
_MAIN = 'import sys; from itasc_bringup.recording.writer import main; sys.exit(main(sys.argv[1:]))'


class BagProcess:
    """The recording process's side: a bag written by a process of its own. Not thread-safe: one
    caller at a time (the :class:`~.recorder.Recorder` holds its lock)."""

    def __init__(self, path: str | os.PathLike, *, compression: str = 'zstd', library: str = 'itasc_bringup',
                 custom_data: Mapping[str, str] | None = None) -> None:
        from .bag import prepare_recording
        prepare_recording(Path(path))  # BagExists or CannotRecord here, before anything starts
        custom = [arg for key, value in (custom_data or {}).items() for arg in ('--custom-data', f'{key}={value}')]
        self._process = subprocess.Popen(
            [sys.executable, '-c', _MAIN, os.fspath(path), '--prepared', '--compression', compression,
             '--library', library, *custom], stdin=subprocess.PIPE, start_new_session=True)
        self._fd = self._process.stdin.fileno()
        try:  # room for a few batches: the writer catches up between them
            fcntl.fcntl(self._fd, fcntl.F_SETPIPE_SZ, PIPE_SIZE)
        except OSError:  # above /proc/sys/fs/pipe-max-size: the default (64 KiB) does
            pass
        os.set_blocking(self._fd, False)
        #: frames not (wholly) in the pipe yet, the first maybe in part
        self._unsent: collections.deque[memoryview] = collections.deque()
        self._pending = bytearray()
        self._keys = 0
        self._broken = False
        self.closed = False

    def add_topic(self, topic: str, type_name: str, *, profiles: list[dict[str, Any]]) -> int:
        """Register ``topic`` (its QoS profiles as :func:`~.bag.qos_profiles` gives them); returns its key."""
        self._keys += 1
        self._flush_pending()
        self._send(self._frame(TOPIC, pickle.dumps((self._keys, topic, type_name, profiles))))
        return self._keys

    def write(self, key: int, data: bytes, *, time_ns: int, publish_time_ns: int | None = None) -> None:
        self.write_all([(key, data, time_ns, time_ns if publish_time_ns is None else publish_time_ns)])

    def write_all(self, records: Iterable[tuple[int, bytes, int, int]]) -> None:
        """Write each ``(key, data, time_ns, publish_time_ns)`` (a tick's samples at once)."""
        pending, pack = self._pending, _RECORD.pack
        for key, data, time_ns, publish_time_ns in records:
            pending += pack(key, time_ns, publish_time_ns, len(data))
            pending += data
        if len(pending) >= BATCH:
            self._flush_pending()
        elif self._unsent:
            self._send_what_fits()

    @property
    def failure(self) -> str | None:
        """Why the recording is incomplete (its process ended before it was closed, or failed),
        None while it is not."""
        code = self._process.poll()
        if code is None:
            return 'the recording process does not take what is recorded' if self._broken else None
        if code == 0 and self.closed:
            return None
        how = f'was killed (signal {-code})' if code < 0 else f'failed (exit code {code})' if code else 'ended'
        return f'the recording process {how}' + ('' if self.closed else ' while the run went on')

    @property
    def unsent(self) -> int:
        """Bytes handed over that the pipe has not taken yet."""
        return len(self._pending) + sum(len(frame) for frame in self._unsent)

    def flush(self) -> None:
        """Send what waits, and have the writer flush the file."""
        self._flush_pending()
        self._send(self._frame(FLUSH, b''))

    def close(self, *, timeout: float = 30.0) -> None:
        """Send what waits, have the writer finish the bag, and wait until it did."""
        if self.closed:
            return
        self.closed = True
        self._flush_pending()
        self._send(self._frame(CLOSE, b''))
        deadline = time.monotonic() + timeout
        while self._unsent and not self._broken and time.monotonic() < deadline:
            select.select([], [self._fd], [], max(0.0, deadline - time.monotonic()))
            self._send_what_fits()
        try:
            self._process.stdin.close()
        except OSError:
            pass
        try:
            self._process.wait(timeout=max(0.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            self._process.kill()
            self._process.wait()

    def _flush_pending(self) -> None:
        if self._pending:
            self._send(self._frame(MESSAGES, bytes(self._pending)))
            self._pending.clear()

    def _send(self, frame: bytes) -> None:
        self._unsent.append(memoryview(frame))
        self._send_what_fits()

    def _send_what_fits(self) -> None:
        unsent = self._unsent
        while unsent and not self._broken:
            try:
                written = os.write(self._fd, unsent[0])
            except BlockingIOError:  # the pipe is full: the next call goes on
                return
            except InterruptedError:
                continue
            except BrokenPipeError:  # the writer is gone: nothing more can be recorded
                self._broken = True
                unsent.clear()
                return
            if written == len(unsent[0]):
                unsent.popleft()
            else:
                unsent[0] = unsent[0][written:]

    @staticmethod
    def _frame(kind: int, payload: bytes) -> bytes:
        return _FRAME.pack(kind, len(payload)) + payload


def _frames(fd: int, *, poll: float = POLL) -> Iterable[tuple[int, bytes]]:
    """The frames on ``fd`` until it ends, read without ever blocking in a read: what the pipe
    holds is taken every ``poll`` seconds (see the module docstring)."""
    os.set_blocking(fd, False)
    buffer = bytearray()
    offset = 0
    while True:
        try:
            chunk = os.read(fd, PIPE_SIZE)
        except BlockingIOError:
            time.sleep(poll)
            continue
        if not chunk:
            return
        buffer += chunk
        while len(buffer) - offset >= _FRAME.size:
            kind, size = _FRAME.unpack_from(buffer, offset)
            end = offset + _FRAME.size + size
            if end > len(buffer):
                break
            yield kind, bytes(buffer[offset + _FRAME.size:end])
            offset = end
        del buffer[:offset]
        offset = 0


def _records(payload: bytes) -> Iterable[tuple[int, int, int, bytes]]:
    offset = 0
    while offset < len(payload):
        key, log_ns, publish_ns, size = _RECORD.unpack_from(payload, offset)
        offset += _RECORD.size
        yield key, log_ns, publish_ns, payload[offset:offset + size]
        offset += size


def main(argv: list[str] | None = None) -> int:
    """``main([PATH, ...])``: write the frames on stdin into the bag PATH (the writer process)."""
    from .bag import BagWriter

    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('path')
    parser.add_argument('--prepared', action='store_true', help='its empty MCAP file was made (prepare_recording)')
    parser.add_argument('--compression', default='zstd')
    parser.add_argument('--library', default='itasc_bringup')
    parser.add_argument('--custom-data', action='append', default=[], metavar='KEY=VALUE')
    args = parser.parse_args(argv)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the recording process closes the bag, or its end does
    try:
        bag = BagWriter(args.path, compression=args.compression, library=args.library, prepared=args.prepared,
                        custom_data=dict(item.split('=', 1) for item in args.custom_data))
    except OSError as err:
        print(f'error: recording {args.path}: {err}', file=sys.stderr)
        return 1
    failure: OSError | None = None
    try:
        _write(bag, sys.stdin.fileno())
    except OSError as err:  # the disk full, the file system gone: what was flushed before stays
        failure = err
    try:
        bag.close()
    except OSError as err:
        failure = failure or err
    if failure is not None:
        print(f'error: recording {args.path}: {failure.strerror or failure}; what was written until then can be '
              f'read after itasc-recover {bag.mcap_path}', file=sys.stderr)
        return 1
    return 0


def _write(bag, fd: int) -> None:
    """Write the frames on ``fd`` into ``bag`` until the pipe ends or says CLOSE."""
    channels: dict[int, int] = {}
    flushed = time.monotonic()
    for kind, payload in _frames(fd):
        if kind == TOPIC:
            key, topic, type_name, profiles = pickle.loads(payload)
            channels[key] = bag.add_topic(topic, type_name, profiles=profiles)
        elif kind == MESSAGES:
            for key, log_ns, publish_ns, data in _records(payload):
                bag.write(channels[key], data, time_ns=log_ns, publish_time_ns=publish_ns)
        elif kind == CLOSE:
            return
        if kind == FLUSH or time.monotonic() - flushed > FLUSH_PERIOD:
            bag.flush()
            flushed = time.monotonic()


if __name__ == '__main__':
    raise SystemExit(main())

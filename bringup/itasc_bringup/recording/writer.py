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

The composite processes of this machine record their own outputs (``--deploy per-composite``,
:mod:`itasc_core.communication.sample_stream`): :class:`BagProcess` listens on an abstract Unix socket
(:attr:`BagProcess.address`) that they connect to, the writer process takes their frames as it takes
the pipe's (the same frames; one channel per topic, whoever announces it) and names every topic that
comes that way on its standard output, one line each, for the recorder (:meth:`BagProcess.streamed`),
which then reads none of them over DDS. Told to close, it takes what the streams still send until
each has ended (their processes end after their composite stopped), :data:`STREAMS_LINGER` at most.
"""

from __future__ import annotations

import argparse
import fcntl
import os
import pickle
import secrets
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from itasc_core.communication.sample_stream import (CLOSE, FLUSH, FRAME, MESSAGES, RECORD, TOPIC, FrameSender,
                                                    abstract_address)

__all__ = ['BagProcess', 'main']

#: The pipe's size asked for [bytes] (Linux allows up to /proc/sys/fs/pipe-max-size, 1 MiB by default).
PIPE_SIZE = 1 << 20
#: The writer flushes the file at least this often [s] (``mcap recover`` salvages what was flushed).
FLUSH_PERIOD = 1.0
#: The writer takes what the pipe and the streams hold this often [s].
POLL = 0.01
#: Told to close, the writer waits this long at most for the streams to end [s].
STREAMS_LINGER = 5.0
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
        #: the name of the abstract Unix socket the composite processes stream their outputs to
        self.address = f'itasc-recording-{os.getpid()}-{secrets.token_hex(6)}'
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as listening:
            listening.bind(abstract_address(self.address))
            listening.listen(64)  # connections wait here until the writer process takes them
            self._process = subprocess.Popen(
                [sys.executable, '-c', _MAIN, os.fspath(path), '--prepared', '--compression', compression,
                 '--library', library, '--listen-fd', str(listening.fileno()), *custom],
                stdin=subprocess.PIPE, stdout=subprocess.PIPE, pass_fds=(listening.fileno(),),
                start_new_session=True)
        fd = self._process.stdin.fileno()
        try:  # room for a few batches: the writer catches up between them
            fcntl.fcntl(fd, fcntl.F_SETPIPE_SZ, PIPE_SIZE)
        except OSError:  # above /proc/sys/fs/pipe-max-size: the default (64 KiB) does
            pass
        self._sender = FrameSender(fd)
        self._told = self._process.stdout.fileno()
        os.set_blocking(self._told, False)
        self._told_buffer = b''
        self._names: list[str] = []
        self.closed = False

    def add_topic(self, topic: str, type_name: str, *, profiles: list[dict[str, Any]]) -> int:
        """Register ``topic`` (its QoS profiles as :func:`~.bag.qos_profiles` gives them); returns its key."""
        return self._sender.add_topic(topic, type_name, profiles=profiles)

    def write(self, key: int, data: bytes, *, time_ns: int, publish_time_ns: int | None = None) -> None:
        self.write_all([(key, data, time_ns, time_ns if publish_time_ns is None else publish_time_ns)])

    def write_all(self, records: Iterable[tuple[int, bytes, int, int]]) -> None:
        """Write each ``(key, data, time_ns, publish_time_ns)`` (a tick's samples at once)."""
        self._sender.write_all(records)

    def streamed(self) -> list[str]:
        """The topics that the composite processes' streams announced since the last call."""
        if not self.closed:
            self._hear()
        names, self._names = self._names, []
        return names

    def _hear(self) -> None:
        try:
            chunk = os.read(self._told, 1 << 16)
        except OSError:  # nothing yet (BlockingIOError), or the writer is gone
            return
        *lines, self._told_buffer = (self._told_buffer + chunk).split(b'\n')
        self._names += [line.decode() for line in lines]

    @property
    def failure(self) -> str | None:
        """Why the recording is incomplete (its process ended before it was closed, or failed),
        None while it is not."""
        code = self._process.poll()
        if code is None:
            return 'the recording process does not take what is recorded' if self._sender.broken else None
        if code == 0 and self.closed:
            return None
        how = f'was killed (signal {-code})' if code < 0 else f'failed (exit code {code})' if code else 'ended'
        return f'the recording process {how}' + ('' if self.closed else ' while the run went on')

    @property
    def unsent(self) -> int:
        """Bytes handed over that the pipe has not taken yet."""
        return self._sender.unsent

    def flush(self) -> None:
        """Send what waits, and have the writer flush the file."""
        self._sender.send(FLUSH)

    def close(self, *, timeout: float = 30.0) -> None:
        """Send what waits, have the writer finish the bag, and wait until it did."""
        if self.closed:
            return
        self.closed = True
        deadline = time.monotonic() + timeout
        self._sender.send(CLOSE)
        self._sender.finish(deadline=deadline)
        try:
            self._process.stdin.close()
        except OSError:
            pass
        try:
            self._process.wait(timeout=max(0.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            self._process.kill()
            self._process.wait()
        self._hear()  # the names it told last
        self._process.stdout.close()


class _Frames:
    """The frames coming on one file descriptor (the pipe, a stream's socket), read without ever
    blocking in a read (see the module docstring); ``keys``: the stream's topic keys -> channels."""

    def __init__(self, fd: int) -> None:
        self.fd = fd
        os.set_blocking(fd, False)
        self.keys: dict[int, int] = {}
        self.ended = False
        self._buffer = bytearray()

    def take(self) -> list[tuple[int, bytes]]:
        """The whole frames that came since the last call; ``ended`` once the other side closed."""
        buffer = self._buffer
        while not self.ended:
            try:
                chunk = os.read(self.fd, PIPE_SIZE)
            except BlockingIOError:
                break
            except ConnectionResetError:
                chunk = b''
            if not chunk:
                self.ended = True  # a frame cut off by the end (a process killed while sending) is dropped
            buffer += chunk
        frames, offset = [], 0
        while len(buffer) - offset >= FRAME.size:
            kind, size = FRAME.unpack_from(buffer, offset)
            end = offset + FRAME.size + size
            if end > len(buffer):
                break
            frames.append((kind, bytes(buffer[offset + FRAME.size:end])))
            offset = end
        del buffer[:offset]
        return frames


def _records(payload: bytes) -> Iterable[tuple[int, int, int, bytes]]:
    offset = 0
    while offset < len(payload):
        key, log_ns, publish_ns, size = RECORD.unpack_from(payload, offset)
        offset += RECORD.size
        yield key, log_ns, publish_ns, payload[offset:offset + size]
        offset += size


def main(argv: list[str] | None = None) -> int:
    """``main([PATH, ...])``: write the frames on stdin (and on the streams that connect to the
    socket ``--listen-fd``) into the bag PATH (the writer process)."""
    from .bag import BagWriter

    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('path')
    parser.add_argument('--prepared', action='store_true', help='its empty MCAP file was made (prepare_recording)')
    parser.add_argument('--compression', default='zstd')
    parser.add_argument('--library', default='itasc_bringup')
    parser.add_argument('--custom-data', action='append', default=[], metavar='KEY=VALUE')
    parser.add_argument('--listen-fd', type=int, default=None, help='a listening socket the streams connect to')
    args = parser.parse_args(argv)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the recording process closes the bag, or its end does
    signal.signal(signal.SIGPIPE, signal.SIG_IGN)  # a recorder gone: its end, not ours
    os.set_blocking(sys.stdout.fileno(), False)  # a recorder that does not read the names never stalls this one
    listening = None if args.listen_fd is None else socket.socket(fileno=args.listen_fd)
    try:
        bag = BagWriter(args.path, compression=args.compression, library=args.library, prepared=args.prepared,
                        custom_data=dict(item.split('=', 1) for item in args.custom_data))
    except OSError as err:
        print(f'error: recording {args.path}: {err}', file=sys.stderr)
        return 1
    failure: OSError | None = None
    try:
        _write(bag, sys.stdin.fileno(), listening=listening)
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


def _write(bag, fd: int, *, listening: socket.socket | None) -> None:
    """Write the frames on ``fd`` and on the streams ``listening`` takes into ``bag`` until the pipe
    ends or says CLOSE, and the streams have ended (:data:`STREAMS_LINGER` at most after that)."""
    pipe = _Frames(fd)
    streams: list[_Frames] = []
    channels: dict[str, int] = {}  # topic -> its channel, whoever announced it
    flushed = time.monotonic()
    closing_at: float | None = None
    if listening is not None:
        listening.setblocking(False)
    while True:
        if listening is not None:
            try:
                while True:
                    connection, _ = listening.accept()
                    streams.append(_Frames(connection.detach()))
            except (BlockingIOError, InterruptedError):
                pass
        took = False
        for source in ([pipe] if closing_at is None else []) + streams:
            for kind, payload in source.take():
                took = True
                if kind == TOPIC:
                    key, topic, type_name, profiles = pickle.loads(payload)
                    channel = channels.get(topic)
                    if channel is None:
                        channel = channels[topic] = bag.add_topic(topic, type_name, profiles=profiles)
                    source.keys[key] = channel
                    if source is not pipe:
                        _tell(topic)
                elif kind == MESSAGES:
                    for key, log_ns, publish_ns, data in _records(payload):
                        bag.write(source.keys[key], data, time_ns=log_ns, publish_time_ns=publish_ns)
                elif kind == CLOSE and source is pipe:
                    closing_at = time.monotonic()
                if kind == FLUSH:
                    bag.flush()
                    flushed = time.monotonic()
        for stream in [s for s in streams if s.ended]:
            os.close(stream.fd)
            streams.remove(stream)
        if closing_at is None and pipe.ended:  # the recording process is gone, however it ended
            closing_at = time.monotonic()
        if closing_at is not None:
            if listening is not None:
                listening.close()
                listening = None
            if not streams or time.monotonic() - closing_at > STREAMS_LINGER:
                return
        if time.monotonic() - flushed > FLUSH_PERIOD:
            bag.flush()
            flushed = time.monotonic()
        if not took:
            time.sleep(POLL)


def _tell(topic: str) -> None:
    """Name a streamed topic to the recorder (a line on stdout); a recorder gone is no failure."""
    try:
        os.write(sys.stdout.fileno(), f'{topic}\n'.encode())
    except OSError:
        pass


if __name__ == '__main__':
    raise SystemExit(main())

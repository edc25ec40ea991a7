"""An event storm against a running application, measured (issue #8 item 6; paper §7.2: no event
may be lost).

:func:`storm` starts ``bootstrap pattern_demo --record``, raises ``rate`` events per second for
``seconds`` s on the program composite's event topic from ``sources`` raisers of this process,
waits until every reader of the topic has acknowledged every event, stops the application and
reads the recording. Used by ``test/test_runtime_faults.py`` (which asserts on the figures) and
``bench/bench_storm.py`` (which prints them).
"""

from __future__ import annotations

import os
import signal
import struct
import sys
import threading
import time
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

from processes import Spawned
from recordings import read_recording
from ros_client import ros_node

__all__ = ['StormFigures', 'storm', 'TOPIC']

TOPIC = '/app/program/events'
BOOTSTRAP = [sys.executable, '-m', 'itasc_bringup.bootstrap']


@dataclass
class StormFigures:
    rate: int                 #: events per second asked for
    sent: int
    send_seconds: float       #: how long raising them took (``sent / rate`` if the machine kept up)
    cpu_wait_seconds: float   #: ... of which the raising thread spent waiting for a CPU (run queue)
    acked: bool               #: every reader acknowledged every event within the time allowed
    acked_after: float        #: from the last one raised until then
    received: int             #: e_storm events in the recording
    order_kept: bool          #: each source's events in the recording in the order raised
    gaps: list[str]           #: the Coordinators' "lost events" lines
    rss_before_mb: float      #: the bootstrap's resident memory just before the storm
    rss_peak_mb: float        #: ... its highest sample during the storm and until acknowledged
    rss_after_mb: float       #: ... once every event was acknowledged
    socket_drops: int         #: datagrams the kernel dropped at the bootstrap's sockets
    exit_code: int
    output: str

    @property
    def lost(self) -> int:
        return self.sent - self.received

    def summary(self) -> str:
        acked = 'all acknowledged' if self.acked else 'NOT all acknowledged'
        return (f'{self.sent} events at {self.rate}/s: sent in {self.send_seconds:.1f} s (waiting '
                f'{self.cpu_wait_seconds:.1f} s of it for a CPU), {acked} '
                f'{self.acked_after:.1f} s later; recorded {self.received}, lost {self.lost}, order kept: '
                f'{self.order_kept}; bootstrap RSS {self.rss_before_mb:.0f} MB before, {self.rss_peak_mb:.0f} MB '
                f'peak, {self.rss_after_mb:.0f} MB after; {self.socket_drops} datagrams dropped by the kernel '
                f'(repaired by DDS); load average {os.getloadavg()[0]:.1f}')


def _run_queue_wait() -> float:
    """Seconds the calling thread has spent ready to run but waiting for a CPU (Linux schedstat)."""
    with open(f'/proc/self/task/{threading.get_native_id()}/schedstat') as schedstat:
        return int(schedstat.read().split()[1]) * 1e-9


def _rss_mb(pid: int) -> float:
    with open(f'/proc/{pid}/status') as status:
        return next(int(line.split()[1]) for line in status if line.startswith('VmRSS:')) / 1024


def _socket_drops(pid: int) -> int:
    """Datagrams dropped at the UDP sockets of process ``pid`` so far (/proc/net/udp, last column)."""
    inodes = set()
    for fd in os.listdir(f'/proc/{pid}/fd'):
        try:
            target = os.readlink(f'/proc/{pid}/fd/{fd}')
        except OSError:
            continue
        if target.startswith('socket:['):
            inodes.add(target[8:-1])
    with open('/proc/net/udp') as table:
        rows = [line.split() for line in table.readlines()[1:]]
    return sum(int(row[-1]) for row in rows if row[9] in inodes)


class StormRaiser:
    """Raises ``name`` from one source as fast as DDS takes it: one ``itasc_msgs/Event`` serialised
    up front, and per event only its ``seq`` and ``stamp`` written into a copy of the bytes before
    ``publish`` of the serialised message (an ``EventRaiser`` builds and converts a message per
    event, about half of what a 2-core machine has to spare at 10,000/s). The same events as an
    ``EventRaiser`` of that source would raise: seq from 1, stamped when raised."""

    def __init__(self, node, *, topic: str, source: str, name: str) -> None:
        from rclpy.serialization import serialize_message

        from itasc_core.communication.qos import EVENT_QOS
        from itasc_msgs.msg import Event
        self.publisher = node.create_publisher(Event, topic, EVENT_QOS)
        self._clock = node.get_clock()
        # where seq and stamp lie in the CDR bytes: found by their values, not by layout rules
        marked = Event(source=source, name=name, seq=0x0102030405060708)
        marked.stamp.sec, marked.stamp.nanosec = 0x11223344, 0x55667788
        self._template = serialize_message(marked)
        self._seq_at = self._template.index(struct.pack('<Q', marked.seq))
        self._stamp_at = self._template.index(struct.pack('<iI', marked.stamp.sec, marked.stamp.nanosec))
        self.seq = 0

    def raise_event(self) -> None:
        self.seq += 1
        sec, nanosec = divmod(self._clock.now().nanoseconds, 1_000_000_000)
        data = bytearray(self._template)
        struct.pack_into('<Q', data, self._seq_at, self.seq)
        struct.pack_into('<iI', data, self._stamp_at, sec, nanosec)
        self.publisher.publish(bytes(data))


def storm(mcap: Path, *, rate: int, seconds: float = 10.0, sources: int = 2,
          ack_timeout: float = 120.0) -> StormFigures:
    from rclpy.duration import Duration

    with Spawned([*BOOTSTRAP, 'pattern_demo', '--record', str(mcap)]) as app:
        app.wait_for_line('[state] app: Active.Run.Running', timeout=120)
        pid = app.process.pid
        with ros_node('storm') as (node, executor):
            raisers = [StormRaiser(node, topic=TOPIC, source=f'/storm/source{i}', name='e_storm')
                       for i in range(sources)]

            def matched() -> bool:  # every reader of the topic (the process's event hub, the recorder)
                readers = node.count_subscribers(TOPIC)
                return readers >= 2 and all(r.publisher.get_subscription_count() == readers for r in raisers)

            deadline = time.monotonic() + 10
            while not matched() and time.monotonic() < deadline:
                executor.spin_once(timeout_sec=0.05)
            assert matched(), 'the composite\'s event readers did not all match the storm\'s publishers'
            rss_before, drops_before = _rss_mb(pid), _socket_drops(pid)
            start, sent, rss_peak, waited = time.monotonic(), 0, rss_before, _run_queue_wait()
            total = int(rate * seconds)
            while sent < total:
                due = min(total, int((time.monotonic() - start) * rate) + 1)
                while sent < due:
                    raisers[sent % sources].raise_event()
                    sent += 1
                rss_peak = max(rss_peak, _rss_mb(pid))
                time.sleep(0.002)
            send_seconds, waited = time.monotonic() - start, _run_queue_wait() - waited
            ack_deadline, acked = time.monotonic() + ack_timeout, True
            for raiser in raisers:
                while acked and not raiser.publisher.wait_for_all_acked(Duration(seconds=0.1)):
                    rss_peak = max(rss_peak, _rss_mb(pid))
                    acked = time.monotonic() < ack_deadline
            acked_after = time.monotonic() - start - send_seconds
            rss_after, drops = _rss_mb(pid), _socket_drops(pid) - drops_before
        os.killpg(pid, signal.SIGINT)
        code = app.finish(timeout=120)
    events = [m for m in read_recording(mcap, TOPIC).get(TOPIC, []) if m.name == 'e_storm']
    by_source = defaultdict(list)
    for m in events:
        by_source[m.source].append(m.seq)
    return StormFigures(
        rate=rate, sent=total, send_seconds=send_seconds, cpu_wait_seconds=waited, acked=acked,
        acked_after=acked_after, received=len(events),
        order_kept=all(seqs == list(range(1, len(seqs) + 1)) for seqs in by_source.values()),
        gaps=[line for line in app.err.splitlines() if 'lost events' in line],
        rss_before_mb=rss_before, rss_peak_mb=max(rss_peak, rss_after), rss_after_mb=rss_after,
        socket_drops=drops, exit_code=code, output=app.output())

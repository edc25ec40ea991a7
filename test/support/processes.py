"""Processes started by tests: time-bounded reads, and nothing left running afterwards.

A test that waits for a line a process never prints must fail with what the process did print,
and where it is stuck (the Python stacks of its threads, for a process of ours that dumps them on
SIGUSR1; the processes of its group with their state, and the native stacks of the stuck one when
gdb is there: a thread stuck in a C library shows in Python only as the call into it), not hang;
and a process a test started (with the composite processes it started in turn) must be gone when
the test ends, whatever the test's outcome. A leftover holding the test run's output
pipe would otherwise keep CI waiting long after pytest finished.
"""

from __future__ import annotations

import os
import queue
import shutil
import signal
import subprocess
import threading
import time
from typing import Sequence

__all__ = ['Spawned', 'started_here']


def started_here(*, command: str = '') -> dict[int, str]:
    """Running processes started, directly or not, by this test process: pid -> command line.

    Recognised by the ``ITASC_TEST_SESSION=<pid of the test process>`` in their environment
    (conftest.py sets it), which every descendant inherits, even one whose parent died; or, for a
    composite process forked by a zygote (``itasc_core.composition.zygote``: its command line is
    written over the memory /proc shows its environment from), by an ancestor that has it. Only
    those whose command line contains ``command``. Linux (``/proc``).
    """
    mark = f'ITASC_TEST_SESSION={os.getpid()}'.encode()
    marked, parents, lines = set(), {}, {}
    for entry in os.scandir('/proc'):
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        pid = int(entry.name)
        try:
            with open(f'/proc/{pid}/environ', 'rb') as environ:
                if mark in environ.read().split(b'\0'):
                    marked.add(pid)
            with open(f'/proc/{pid}/stat', 'rb') as stat:
                parents[pid] = int(stat.read().rsplit(b')', 1)[1].split()[1])
            with open(f'/proc/{pid}/cmdline', 'rb') as cmdline:
                lines[pid] = cmdline.read().replace(b'\0', b' ').decode(errors='replace').strip()
        except OSError:  # gone meanwhile, or not ours to read
            continue

    def ours(pid: int) -> bool:
        seen = set()
        while pid in parents and pid not in seen:
            if pid in marked:
                return True
            seen.add(pid)
            pid = parents[pid]
        return pid == os.getpid()

    return {pid: line for pid, line in lines.items() if line and ours(pid) and command in line}


def _catches(pid: int, signum: int) -> bool:
    """Whether process ``pid`` has a handler for ``signum`` (``SigCgt`` of ``/proc/<pid>/status``)."""
    try:
        with open(f'/proc/{pid}/status') as status:
            caught = next(int(line.split()[1], 16) for line in status if line.startswith('SigCgt:'))
    except (OSError, StopIteration):
        return False
    return bool(caught >> (signum - 1) & 1)


class Spawned:
    """A process in its own process group, its stdout and stderr collected line by line.

    Use as a context manager; leaving it kills the whole group if the process is still running.

    The group is in the test's session, not a session of its own: Linux gives each session its own
    scheduling group (autogroup), and on a 2-core machine a light process alone in its group (a
    200 Hz fake driver) went without the CPU for up to 0.8 s, runnable all along, while the other
    test worker started its applications: long enough for the application's silent-driver Monitor
    to go to Safety. In the test's session it shares the worker's group and runs on time.
    """

    def __init__(self, args: Sequence[str], **popen) -> None:
        self.process = subprocess.Popen(list(args), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                        process_group=0, **popen)
        self.stdout: list[str] = []
        self.stderr: list[str] = []
        self._lines: queue.Queue[str | None] = queue.Queue()
        self._readers = [
            threading.Thread(target=self._read, args=(self.process.stdout, self.stdout, True), daemon=True),
            threading.Thread(target=self._read, args=(self.process.stderr, self.stderr, False), daemon=True)]
        for reader in self._readers:
            reader.start()

    def _read(self, stream, into: list[str], announce: bool) -> None:
        for line in stream:
            into.append(line)
            if announce:
                self._lines.put(line)
        if announce:
            self._lines.put(None)

    def wait_for_line(self, prefix: str, *, timeout: float) -> str:
        """The first stdout line not yet waited for that starts with ``prefix`` (lines printed
        before this call count, unless :meth:`forget_lines` dropped them); fails after ``timeout`` s."""
        deadline = time.monotonic() + timeout
        while (left := deadline - time.monotonic()) > 0:
            try:
                line = self._lines.get(timeout=left)
            except queue.Empty:
                break
            if line is None:
                raise AssertionError(f'process ended (exit {self.process.wait()}) before printing {prefix!r}\n'
                                     + self.output())
            if line.startswith(prefix):
                return line
        self.dump_stacks()
        raise AssertionError(f'no line {prefix!r} within {timeout} s\n' + self.output() + self.where())

    def forget_lines(self) -> list[str]:
        """Drop the stdout lines printed so far from what :meth:`wait_for_line` looks at (they stay
        in :attr:`stdout`), so that the next wait sees only what comes after this call; returns them."""
        dropped = []
        while True:
            try:
                line = self._lines.get_nowait()
            except queue.Empty:
                return dropped
            if line is None:  # the end of the output: keep it for the next wait
                self._lines.put(None)
                return dropped
            dropped.append(line)

    def send_signal(self, signum: int) -> None:
        self.process.send_signal(signum)

    def finish(self, *, timeout: float) -> int:
        """Wait for the process to end by itself and for its output; returns its exit code."""
        try:
            code = self.process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.dump_stacks()
            raise AssertionError(f'process still running after {timeout} s\n' + self.output() + self.where()) from None
        for reader in self._readers:
            reader.join(timeout=10)
        return code

    def dump_stacks(self, *, wait: float = 2.0) -> None:
        """Have a stuck process write the stacks of its threads to its stderr (``faulthandler`` on
        SIGUSR1, which the bootstrap and the composite processes register), and wait for them. A
        process that does not catch SIGUSR1 is left alone: the signal would end it."""
        if self.process.poll() is not None or not _catches(self.process.pid, signal.SIGUSR1):
            return
        before = len(self.stderr)
        self.send_signal(signal.SIGUSR1)
        deadline = time.monotonic() + wait
        while time.monotonic() < deadline and not any('most recent call first' in line
                                                      for line in self.stderr[before:]):
            time.sleep(0.05)
        time.sleep(0.2)  # the rest of the dump

    def where(self) -> str:
        """The processes of this one's group (state, kernel wait channel, age, command line) and the
        native stacks of this one's threads (gdb, if installed and allowed to attach)."""
        if self.process.poll() is not None:
            return ''
        parts = []
        for command in (['ps', '-e', '-ww', '-o', 'pgid,pid,ppid,stat,wchan:32,etime,args'],
                        *([['gdb', '-batch', '-p', str(self.process.pid), '-ex', 'thread apply all bt 30']]
                          if shutil.which('gdb') else [])):
            try:
                done = subprocess.run(command, capture_output=True, text=True, timeout=30)
            except (OSError, subprocess.TimeoutExpired) as err:
                parts.append(f'--- {command[0]}: {err}')
                continue
            out = done.stdout
            if command[0] == 'ps':  # the header, and the processes of this one's group
                lines = out.splitlines()
                out = '\n'.join(lines[:1] + [line for line in lines[1:] if line.split()[0] == str(self.process.pid)])
            parts.append(f'--- {command[0]}\n{out[-12000:]}\n{done.stderr[-2000:]}')
        return '\n' + '\n'.join(parts)

    @property
    def out(self) -> str:
        return ''.join(self.stdout)

    @property
    def err(self) -> str:
        return ''.join(self.stderr)

    def output(self, *, tail: int = 8000) -> str:
        return f'--- stdout (tail)\n{self.out[-tail:]}\n--- stderr (tail)\n{self.err[-tail:]}'

    def kill(self) -> None:
        """SIGKILL the process group (the process and every process it started)."""
        try:
            os.killpg(self.process.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        self.process.wait()

    def __enter__(self) -> Spawned:
        return self

    def __exit__(self, *exc) -> None:
        if self.process.poll() is None:
            self.kill()

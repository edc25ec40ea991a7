"""Composite processes forked from a zygote (paper §3.1: the Composer deploys a child composite,
here in a process of its own): a copy of this process, made before it starts ROS, forks the process
of each child composite, which so starts with the runtime and the model's kinds already imported.
Started as a new interpreter, each composite process spends ~0.7 s of CPU importing them; on a
machine of two cores that was most of a per-composite bring-up (issue #9: < 3 s).

A fork is safe only from a process without other threads, so the zygote is made before
``rclpy.init`` (DDS starts threads) and stays as it is. It forks twice per child: the child is
re-parented to the process that asked for it (a child subreaper), which waits for it as for a child
of its own; :class:`ForkedProcess` answers like :class:`subprocess.Popen`. The child shows the
command line a started composite process has (``ps``, ``pgrep -f itasc_core.composition.host``).
The zygote ends when the process that made it does (end of its request pipe). Should it end before
(killed), composite processes are started as new interpreters from then on: slower, never refused.
"""

from __future__ import annotations

import ctypes
import json
import os
import select
import signal
import subprocess
import sys
import threading
import traceback
from typing import Iterator

from .model import CompositeModel, EntityModel

__all__ = ['Zygote', 'ForkedProcess', 'HOST_COMMAND', 'zygote_for']

#: How a composite process is started without a zygote (``argv`` follows).
HOST_COMMAND = [sys.executable, '-m', 'itasc_core.composition.host']

_PR_SET_CHILD_SUBREAPER = 36  # <linux/prctl.h>


class ForkedProcess:
    """A composite process forked by a :class:`Zygote`, re-parented to this process: ``poll``,
    ``wait``, ``kill``, ``returncode`` as :class:`subprocess.Popen` has them."""

    def __init__(self, pid: int, *, args: list[str]) -> None:
        self.pid = pid
        self.args = args
        self.returncode: int | None = None
        self._lock = threading.Lock()
        #: readable once the process ended: a wait blocks on it, as Popen's blocks in waitpid
        self._pidfd = os.pidfd_open(pid)

    def __del__(self) -> None:
        os.close(self._pidfd)

    def poll(self) -> int | None:
        with self._lock:
            if self.returncode is None:
                done, status = os.waitpid(self.pid, os.WNOHANG)
                if done:
                    self.returncode = os.waitstatus_to_exitcode(status)
            return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        select.select([self._pidfd], [], [], timeout)
        code = self.poll()
        if code is None:
            raise subprocess.TimeoutExpired(self.args, timeout or 0.0)
        return code

    def send_signal(self, signum: int) -> None:
        if self.poll() is None:
            os.kill(self.pid, signum)

    def kill(self) -> None:
        self.send_signal(signal.SIGKILL)

    def terminate(self) -> None:
        self.send_signal(signal.SIGTERM)


class Zygote:
    """Forks composite processes (``itasc_core.composition.host`` with ``argv``) on request."""

    def __init__(self, *, requests: int, answers: int, pid: int) -> None:
        self._requests, self._answers, self.pid = requests, answers, pid
        self._lock = threading.Lock()
        self.gone = False

    @classmethod
    def make(cls) -> Zygote | None:
        """Fork the zygote of this process now, or None when forking is not safe or not possible
        here (other threads run, or the system has no child subreapers): processes are then
        started as new interpreters."""
        if threading.active_count() > 1 or not sys.platform.startswith('linux'):
            return None
        if ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0) != 0:
            return None
        requests_r, requests_w = os.pipe()
        answers_r, answers_w = os.pipe()
        sys.stdout.flush()
        sys.stderr.flush()
        pid = os.fork()
        if pid == 0:
            os.close(requests_w)
            os.close(answers_r)
            _serve(requests_r, answers_w)
        os.close(requests_r)
        os.close(answers_w)
        return cls(requests=requests_w, answers=answers_r, pid=pid)

    def start(self, argv: list[str]) -> ForkedProcess | subprocess.Popen:
        """Fork the composite process of ``argv`` (the arguments of ``itasc_core.composition.host``);
        once the zygote is gone, start it as a new interpreter."""
        with self._lock:
            if not self.gone:
                try:
                    os.write(self._requests, (json.dumps(argv) + '\n').encode())
                    return ForkedProcess(int(_read_line(self._answers)), args=[*HOST_COMMAND, *argv])
                except (OSError, RuntimeError) as err:
                    self.gone = True
                    from rclpy.logging import get_logger
                    get_logger('itasc_zygote').warning(
                        f'the zygote (pid {self.pid}) is gone ({err}): composite processes are started as new '
                        'interpreters from now on')
        return subprocess.Popen([*HOST_COMMAND, *argv])


def _read_line(fd: int) -> str:
    line = b''
    while not line.endswith(b'\n'):
        chunk = os.read(fd, 1)
        if not chunk:
            raise RuntimeError('the zygote of this process is gone')
        line += chunk
    return line.decode()


def _serve(requests: int, answers: int) -> None:
    """The zygote: for each request, fork twice and answer the composite process's pid; end with
    the pipe of requests."""
    import setproctitle

    for signum in (signal.SIGINT, signal.SIGTERM):  # a Ctrl-C is for the process that made it
        signal.signal(signum, signal.SIG_IGN)
    setproctitle.setproctitle(f'{sys.executable} -m {__name__} (forks the composite processes of {os.getppid()})')
    try:
        while True:
            try:
                argv = json.loads(_read_line(requests))
            except RuntimeError:
                break
            pids_r, pids_w = os.pipe()
            middle = os.fork()
            if middle == 0:
                os.close(pids_r)
                # the title first, so that the child has it from its first instant
                setproctitle.setproctitle(' '.join([*HOST_COMMAND, *argv]))
                child = os.fork()
                if child == 0:
                    for fd in (requests, answers, pids_w):
                        os.close(fd)
                    _run(argv)
                os.write(pids_w, f'{child}\n'.encode())
                os._exit(0)
            os.close(pids_w)
            child = int(_read_line(pids_r))
            os.close(pids_r)
            os.waitpid(middle, 0)  # the child is now re-parented to the process that asked for it
            os.write(answers, f'{child}\n'.encode())
    finally:
        os._exit(0)


def _run(argv: list[str]) -> None:
    """The composite process: ``itasc_core.composition.host`` with ``argv``; never returns."""
    code = 1
    try:
        from . import host

        sys.argv = [host.__file__, *argv]  # as a started process has them (rclpy.init reads them)
        code = host.main(argv)
    except SystemExit as exit_:
        code = exit_.code if isinstance(exit_.code, int) else int(exit_.code is not None)
    except BaseException:  # noqa: BLE001 - reported as an interpreter would, then the exit code
        traceback.print_exc()
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)


def zygote_for(model: CompositeModel) -> Zygote | None:
    """The zygote of a process that hosts composite ``model`` and deploys its children in processes of their own, with
    every kind of its descendants imported; None when ``model`` has no child composite, now or in a
    composition step."""
    from .registry import resolve_kind

    composites = [c for c in _members(model) if isinstance(c, CompositeModel)]
    if not composites:
        return None
    for composite in composites:
        for member in _members(composite, deep=True):
            if not isinstance(member, CompositeModel):
                resolve_kind(member.kind)
    return Zygote.make()


def _members(model: CompositeModel, *, deep: bool = False) -> Iterator[EntityModel | CompositeModel]:
    """The entities and child composites of ``model`` and of its composition steps (with ``deep``,
    of its descendants too)."""
    for member in [*model.entities, *(e for step in model.composition_steps.values() for e in (*step.add, *step.swap))]:
        yield member
        if deep and isinstance(member, CompositeModel):
            yield from _members(member, deep=True)

"""One running instance of an application per machine and ROS domain (the bootstrap's start-up
check; paper §6.1: the root Coordinator owns the application's events).

Two instances of one application in one ROS domain share every topic: each one's Coordinators
take the other's events (``pattern_demo`` started twice: the running one's program switched state
on the other's Monitor event), its ``e_<app>_configure`` included. ROS cannot tell them apart by name,
and DDS discovery takes 0.2-0.5 s here, too long to wait for at every start. So the bootstrap
holds a lock named after the ROS domain and the application (a POSIX record lock on a file in the
temporary directory) from before it joins DDS to its exit. The kernel releases it however the
process ends, and the processes it forks do not inherit it (a composite's process that outlives
the bootstrap does not hold it). A second bootstrap of the same application in the same domain
on the same machine finds it held and stops before anything starts. Instances on two machines of
one domain are not seen by this check.
"""

from __future__ import annotations

import errno
import fcntl
import os
import tempfile
import weakref
from pathlib import Path

from itasc_core.communication.dds import domain_id

__all__ = ['AlreadyRunning', 'InstanceLock']


class AlreadyRunning(RuntimeError):
    """The application runs already in this ROS domain, on this machine."""


class InstanceLock:
    """The lock of application ``app`` in ROS domain ``domain`` (default: this process's),
    held from :meth:`acquire` until :meth:`release` or the process's end."""

    def __init__(self, app: str, *, domain: int | None = None, directory: str | os.PathLike | None = None) -> None:
        self.app = app
        self.domain = domain_id() if domain is None else domain
        self.path = Path(directory or tempfile.gettempdir()) / f'itasc-ros-domain-{self.domain}-{app}.lock'
        self._release: weakref.finalize | None = None

    def acquire(self) -> None:
        """Take the lock, or raise :class:`AlreadyRunning` naming the process that holds it."""
        try:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o666)
            mode = fcntl.LOCK_EX
            try:  # whoever runs next, another user too, may take it
                os.fchmod(fd, 0o666)
            except PermissionError:
                pass
        except PermissionError:  # another user's file: a shared lock still meets an exclusive one
            fd = os.open(self.path, os.O_RDONLY)
            mode = fcntl.LOCK_SH
        try:
            fcntl.lockf(fd, mode | fcntl.LOCK_NB)
        except OSError as err:
            if err.errno not in (errno.EACCES, errno.EAGAIN):
                os.close(fd)
                raise
            holder = os.pread(fd, 32, 0).decode(errors='replace').strip() or 'unknown'
            os.close(fd)
            raise AlreadyRunning(
                f'{self.app} already runs in ROS domain {self.domain} on this machine (process {holder}): a second '
                f'instance would take its events and configure it again. Stop it first, or run this one in '
                f'another domain (ROS_DOMAIN_ID=...)') from None
        if mode == fcntl.LOCK_EX:
            os.ftruncate(fd, 0)
            os.pwrite(fd, f'{os.getpid()}\n'.encode(), 0)
        self._release = weakref.finalize(self, os.close, fd)  # with this object at the latest

    def release(self) -> None:
        if self._release is not None:
            self._release()  # closing the file releases the lock
            self._release = None

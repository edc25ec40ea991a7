"""Deployment: where entities live (paper §4.4: "models can be deployed in different ways").

One :class:`Runtime` per OS process holds the executor all of the process's entity nodes are added
to. With ``--deploy single`` every composite lives in the bootstrap's process; with
``--deploy per-composite`` every child composite gets a process of its own, started by its
parent's Composer (:mod:`.host`), and everything it exchanges with its parent travels over DDS.
Nodes are destroyed between executor spins, never from inside a callback.
"""

from __future__ import annotations

import faulthandler
import json
import os
import subprocess
import sys
import tempfile
from typing import Iterable, Literal

from rclpy.node import Node

from .model import CompositeModel

__all__ = ['Runtime', 'DeployMode', 'make_executor', 'end_process_within']

DeployMode = Literal['single', 'per-composite']


def make_executor(context=None):
    """The fastest executor available: rclpy's EventsExecutor, else the single-threaded one."""
    try:
        from rclpy.experimental import EventsExecutor
        return EventsExecutor(context=context)
    except ImportError:  # rclpy older than Jazzy
        from rclpy.executors import SingleThreadedExecutor
        return SingleThreadedExecutor(context=context)


def end_process_within(seconds: float = 20.0) -> None:
    """From now on this process has ``seconds`` to end: call it when an executable starts its
    teardown (destroying its nodes, and with the last one its DDS participant), after closing its
    recording.

    Fast DDS 2.14 can deadlock deleting a participant while it handles the discovery of remote
    endpoints (seen here: ``DomainParticipant::set_listener`` busy-waiting in ``rmw_destroy_node``),
    in C code that no Python signal handler interrupts. faulthandler's watchdog is a C thread: past
    the deadline it prints every thread's stack and ends the process with exit code 1, instead of
    leaving it hanging. The deadline also covers the interpreter's own finalization.
    """
    faulthandler.dump_traceback_later(seconds, exit=True)


class Runtime:
    """The executor of this process, the nodes on it and the composite processes it started."""

    def __init__(self, *, executor, mode: DeployMode = 'single') -> None:
        self.executor = executor
        self.mode: DeployMode = mode
        self._retired: list[Node] = []
        self._processes: dict[str, subprocess.Popen] = {}
        self._spec_files: list[str] = []

    def add(self, *nodes: Node) -> None:
        for node in nodes:
            self.executor.add_node(node)

    def retire(self, nodes: Iterable[Node]) -> None:
        """Destroy ``nodes`` after the current callback (see :meth:`reap`)."""
        self._retired.extend(nodes)

    def reap(self) -> int:
        """Destroy retired nodes; call between spins. Returns how many were destroyed."""
        nodes, self._retired = self._retired, []
        for node in nodes:
            self.executor.remove_node(node)
            node.destroy_node()
        return len(nodes)

    def spawn(self, *, model: CompositeModel, namespace: str, parent_namespace: str) -> None:
        """Start a process hosting the composite ``model`` (``--deploy per-composite``)."""
        fd, path = tempfile.mkstemp(prefix=f'itasc_{model.name}_', suffix='.json')
        with os.fdopen(fd, 'w') as out:
            json.dump(model.model_dump(by_alias=True, exclude_defaults=True), out)
        self._spec_files.append(path)
        command = [sys.executable, '-m', 'itasc_core.composition.host', '--spec', path,
                   '--namespace', namespace, '--parent-namespace', parent_namespace,
                   '--parent-pid', str(os.getpid())]
        self._processes[namespace] = subprocess.Popen(command)

    def process(self, namespace: str) -> subprocess.Popen | None:
        return self._processes.get(namespace)

    def join(self, namespace: str, *, timeout: float = 10.0, orderly: bool = True) -> int | None:
        """Wait for a composite process to end (it ends by itself after NotifyStopped); past
        ``timeout``, or at once if not ``orderly``, kill it (it ignores SIGINT and SIGTERM, see
        :mod:`.host`)."""
        process = self._processes.pop(namespace, None)
        if process is None:
            return None
        for end in ((None, process.kill) if orderly else (process.kill,)):
            if end is not None:
                end()
            try:
                return process.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                continue
        return None

    def shutdown(self, *, orderly: bool = True) -> None:
        """End the composite processes: they have stopped in order (``orderly``), or they cannot be
        stopped in order any more (this process ends on a signal, or its parent is gone)."""
        for namespace in list(self._processes):
            self.join(namespace, timeout=5.0, orderly=orderly)
        for path in self._spec_files:
            try:
                os.unlink(path)
            except OSError:
                pass

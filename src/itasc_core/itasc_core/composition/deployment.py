"""Deployment: where entities live (paper §4.4: "models can be deployed in different ways").

One :class:`Runtime` per OS process holds the executor all of the process's entity nodes are added
to. With ``--deploy single`` every composite lives in the bootstrap's process; with
``--deploy per-composite`` every child composite gets a process of its own, started by its
parent's Composer (:mod:`.host`), and everything it exchanges with its parent travels over DDS.
A composite placed on another host (``host:`` in the model) gets a process of its own there,
whatever the mode: the host agent of that name starts it (:mod:`.host_agent`, :mod:`.remote`).
This process's host is ``host`` (default ``$ITASC_HOST``; unset: composites placed on any host run
elsewhere). Nodes are destroyed between executor spins, never from inside a callback; a process
that runs an application destroys them off the tick path (``background``: a node takes some
milliseconds to destroy, a Task composite removed at run time a dozen of them), once they are out
of the executor and no longer listen to events. Nodes built for a run-time re-composition are
built off the tick path too (:meth:`Runtime.off_tick`), and the result handed back to the
executor's thread (:meth:`Runtime.post`). The process's entities share one reader per event topic
(:class:`~..communication.event_hub.EventHub`) and hand data to each other's ports in-process
(:class:`~..communication.ports.LocalBus`). A recorded run's composite processes on this machine
stream their outputs to the recording themselves (``record_to``, :mod:`..communication.sample_stream`).
"""

from __future__ import annotations

import faulthandler
import json
import os
import subprocess
import tempfile
import threading
from concurrent.futures import ThreadPoolExecutor
from typing import Callable, Iterable, Literal, NamedTuple

from rclpy.node import Node

from ..communication.event_hub import EventHub
from ..communication.process_writers import ProcessWriters
from ..communication.ports import LocalBus
from ..pace import PACE
from .model import CompositeModel
from .remote import HostClient, RemoteProcess
from .zygote import HOST_COMMAND, ForkedProcess, Zygote

__all__ = ['Runtime', 'DeployMode', 'RecordTo', 'make_executor', 'end_process_within', 'exit_reason']

DeployMode = Literal['single', 'per-composite']


class RecordTo(NamedTuple):
    """Where a recorded run's composite processes stream their outputs: the writer's abstract Unix
    socket ``address``, every output under ``prefix``."""

    address: str
    prefix: str


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


def exit_reason(process: subprocess.Popen | ForkedProcess | RemoteProcess) -> str:
    """How a composite process that ended by itself ended, in words."""
    if isinstance(process, RemoteProcess):
        return process.failure
    return f'died (exit code {process.returncode})'


class Runtime:
    """The executor of this process, the nodes on it and the composite processes it started."""

    def __init__(self, *, executor, mode: DeployMode = 'single', host: str | None = None,
                 namespace: str = '/', background: bool = False, zygote: Zygote | None = None,
                 record_to: RecordTo | None = None) -> None:
        self.executor = executor
        #: Where the composite processes started on this machine stream their outputs, when the run
        #: is recorded (:mod:`..communication.sample_stream`); None: not recorded, or not that way.
        self.record_to = record_to
        #: Forks the composite processes started here (:mod:`.zygote`); None: new interpreters.
        self.zygote = zygote
        self.mode: DeployMode = mode
        self.host = host or os.environ.get('ITASC_HOST') or None
        self._retired: list[Node] = []
        #: Work off the tick path: building nodes for a re-composition, destroying retired ones. Its
        #: ROS calls are made between the ticks (:mod:`..pace`).
        self._worker = ThreadPoolExecutor(max_workers=1, thread_name_prefix='itasc-runtime',
                                          initializer=PACE.pace_this_thread)
        self._background = background
        self._doomed: list[Node] = []  # out of the executor, to be destroyed off the tick path
        self._doomed_lock = threading.Lock()
        self._processes: dict[str, subprocess.Popen | ForkedProcess | RemoteProcess] = {}
        self._spec_files: list[str] = []
        self._hosts: HostClient | None = None
        #: the process's one reader per event topic, shared by every entity created from now on;
        #: ``namespace``: that of the composite this process was started for
        self.events = EventHub.install(executor, namespace=namespace)
        #: the process's ``/rosout`` and ``/parameter_events`` writers, shared by its entities
        self.writers = ProcessWriters.install(executor, namespace=namespace)
        #: the outputs of this process's entities, by topic (in-process data flow)
        self.bus = LocalBus.of(executor.context)

    def add(self, *nodes: Node) -> None:
        for node in nodes:
            self.executor.add_node(node)

    def retire(self, nodes: Iterable[Node]) -> None:
        """Destroy ``nodes`` after the current callback (see :meth:`reap`)."""
        self._retired.extend(nodes)

    def reap(self, *, wait: bool = False) -> int:
        """Destroy retired nodes; call between spins. Returns how many were retired. They leave the
        executor and stop listening to events at once; they are destroyed once the executor has let
        go of them (a node destroyed earlier may still have a timer fire, and its
        ``~/get_type_description`` service stays in the graph): at the next spin, in the
        ``background`` off the tick path; with ``wait``, at once (the process ends)."""
        nodes, self._retired = self._retired, []
        for node in nodes:
            self.executor.remove_node(node)
            detach = getattr(node, 'detach', None)
            if detach is not None:
                detach()
        with self._doomed_lock:
            self._doomed += nodes
        if wait:
            self._destroy_now()
        elif nodes:  # after the executor processed the removal (its queue is in order)
            self.post(self._destroy_doomed)
        return len(nodes)

    def _destroy_doomed(self) -> None:
        if not self._background:
            self._destroy_now()
            return
        try:
            self.off_tick(self._destroy_now)
        except RuntimeError:  # the worker is shut down: the process ends
            self._destroy_now()

    def _destroy_now(self) -> None:
        with self._doomed_lock:
            nodes, self._doomed = self._doomed, []
        for node in nodes:
            node.destroy_node()

    def off_tick(self, work: Callable[[], object]):
        """Run ``work`` in this process's worker thread; a future of its result."""
        return self._worker.submit(work)

    def post(self, callback: Callable[[], object]) -> None:
        """Run ``callback`` in the executor's thread, between two callbacks (callable from any
        thread)."""
        self.executor.create_task(callback)

    def elsewhere(self, model: CompositeModel) -> bool:
        """Whether child composite ``model`` is placed on another host than this process's."""
        return model.host is not None and model.host != self.host

    def separate(self, model: CompositeModel) -> bool:
        """Whether child composite ``model`` runs in a process of its own (see :meth:`spawn`)."""
        return self.mode == 'per-composite' or self.elsewhere(model)

    def spawn(self, *, model: CompositeModel, namespace: str, parent_namespace: str) -> None:
        """Start a process hosting the composite ``model``: here, or through the agent of its host."""
        if self.elsewhere(model):
            if self._hosts is None:
                self._hosts = HostClient(context=self.executor.context)
            self._processes[namespace] = self._hosts.start(
                host=model.host or '', spec=model.model_dump(by_alias=True, exclude_defaults=True),
                namespace=namespace, parent_namespace=parent_namespace)
            return
        fd, path = tempfile.mkstemp(prefix=f'itasc_{model.name}_', suffix='.json')
        with os.fdopen(fd, 'w') as out:
            json.dump(model.model_dump(by_alias=True, exclude_defaults=True), out)
        self._spec_files.append(path)
        argv = ['--spec', path, '--namespace', namespace, '--parent-namespace', parent_namespace,
                '--parent-pid', str(os.getpid())]
        if self.record_to is not None:
            argv += ['--record-to', self.record_to.address, '--record-prefix', self.record_to.prefix]
        self._processes[namespace] = (self.zygote.start(argv) if self.zygote is not None
                                      else subprocess.Popen([*HOST_COMMAND, *argv]))

    def process(self, namespace: str) -> subprocess.Popen | ForkedProcess | RemoteProcess | None:
        return self._processes.get(namespace)

    @property
    def local_processes(self) -> int:
        """How many composite processes this process started on this machine (not through a host's agent)."""
        return sum(not isinstance(process, RemoteProcess) for process in self._processes.values())

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
        self._worker.shutdown(wait=True)
        self._destroy_now()
        if self._hosts is not None:
            self._hosts.close()
            self._hosts = None
        for path in self._spec_files:
            try:
                os.unlink(path)
            except OSError:
                pass

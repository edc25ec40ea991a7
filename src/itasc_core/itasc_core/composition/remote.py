"""A parent's side of the host agent (paper §4.4, several machines; see :mod:`.host_agent`).

:class:`HostClient` asks host agents to start composites and keeps them held; each composite is a
:class:`RemoteProcess`, which answers like the :class:`subprocess.Popen` of a local composite
process (``poll``, ``wait``, ``kill``, ``returncode``), so that the Composer watches, joins and
kills a composite on another machine as it does a local one. A composite whose agent reports its
process ended, or whose agent falls silent for :data:`~.hosts.LOST_AFTER` (the machine, its
network or the agent is gone), has ended: for its parent a dead process (Safety).

The client's node is spun in a thread of its own, so that a composite can be joined from inside
an executor callback (the Composer's CleanupComputation) while the agent's reports keep arriving.
"""

from __future__ import annotations

import functools
import json
import subprocess
import threading
import time
import uuid

import rclpy
from rclpy.executors import SingleThreadedExecutor

from itasc_msgs.msg import Event

from .hosts import AGENT_QOS, LOST_AFTER, PERIOD, requests_topic, status_topic

__all__ = ['HostClient', 'RemoteProcess', 'LOST', 'FIND_TIMEOUT']

#: ``returncode`` of a composite whose agent was lost (its process's own status is unknown).
LOST = -1
#: How long an agent may take to answer a first start request [s] (before the parent's Coordinator
#: gives up waiting for its children, 10 s).
FIND_TIMEOUT = 5.0


class RemoteProcess:
    """A composite process started by the agent of ``host``."""

    def __init__(self, *, client: 'HostClient', host: str, request: dict) -> None:
        self.host = host
        self.id: str = request['id']
        self.namespace: str = request['namespace']
        self.request = request
        self.pid: int | None = None  # on the agent's machine
        self.returncode: int | None = None
        #: Why it ended, in words (for the Safety reason).
        self.failure = ''
        self._client = client
        self._ended = threading.Event()

    def poll(self) -> int | None:
        return self.returncode

    def wait(self, timeout: float | None = None) -> int | None:
        if not self._ended.wait(timeout):
            raise subprocess.TimeoutExpired(f'{self.namespace} on {self.host}', timeout or 0.0)
        return self.returncode

    def kill(self) -> None:
        self._client.send(self.host, 'kill', [self.id])

    def _end(self, code: int, failure: str) -> None:
        if self.returncode is None:
            self.returncode, self.failure = code, failure
            self._ended.set()


class _Agent:
    """What this client knows about one host agent."""

    def __init__(self, node, host: str) -> None:
        self.requests = node.create_publisher(Event, requests_topic(host), AGENT_QOS)
        self.heard_at: float | None = None
        self.since = time.monotonic()


class HostClient:
    """This process's link to the host agents it deploys composites to."""

    def __init__(self, *, context=None) -> None:
        self._node = rclpy.create_node(f'host_client_{uuid.uuid4().hex[:8]}', namespace='/itasc_hosts',
                                       context=context)
        self._lock = threading.Lock()
        self._agents: dict[str, _Agent] = {}
        self._processes: dict[str, RemoteProcess] = {}
        self._acknowledged: set[str] = set()
        self._seq = 0
        self._executor = SingleThreadedExecutor(context=context)
        self._executor.add_node(self._node)
        self._node.create_timer(PERIOD, self._update)
        self._running = True
        self._thread = threading.Thread(target=self._spin, daemon=True, name='host client')
        self._thread.start()

    def _spin(self) -> None:
        while self._running:
            self._executor.spin_once(timeout_sec=0.05)

    def start(self, *, host: str, spec: dict, namespace: str, parent_namespace: str) -> RemoteProcess:
        """Ask the agent of ``host`` to start the composite ``spec`` at ``namespace``."""
        request = {'id': uuid.uuid4().hex, 'namespace': namespace, 'parent_namespace': parent_namespace,
                   'spec': spec}
        with self._lock:
            if host not in self._agents:
                self._agents[host] = _Agent(self._node, host)
                self._node.create_subscription(Event, status_topic(host),
                                               functools.partial(self._on_status, host), AGENT_QOS)
            process = self._processes[str(request['id'])] = RemoteProcess(client=self, host=host, request=request)
        self.send(host, 'start', request)
        return process

    def send(self, host: str, name: str, detail) -> None:
        with self._lock:
            self._seq += 1
            self._agents[host].requests.publish(Event(
                stamp=self._node.get_clock().now().to_msg(), source=self._node.get_fully_qualified_name(),
                name=name, seq=self._seq, detail=json.dumps(detail)))

    def _on_status(self, host: str, msg: Event) -> None:
        status = json.loads(msg.detail)
        with self._lock:
            self._agents[host].heard_at = time.monotonic()
            for id_, process in self._processes.items():
                reported = status.get(id_)
                if reported is None:
                    continue
                self._acknowledged.add(id_)
                process.pid = reported['pid']
                if reported['exit'] is not None:
                    process._end(reported['exit'], f'died on host {host} (exit code {reported["exit"]})')

    def _update(self) -> None:
        """Hold the composites still running, resend unanswered starts, notice lost agents."""
        now = time.monotonic()
        with self._lock:
            live = [p for p in self._processes.values() if p.returncode is None]
            for process in live:
                agent = self._agents[process.host]
                if agent.heard_at is None and now - agent.since > FIND_TIMEOUT:
                    process._end(LOST, f'could not be started: no host agent {process.host!r} answered '
                                       f'within {FIND_TIMEOUT:.0f} s')
                elif agent.heard_at is not None and now - agent.heard_at > LOST_AFTER:
                    process._end(LOST, f'is lost: host agent {process.host!r} silent for {LOST_AFTER:.0f} s')
        for host in {p.host for p in live}:
            self.send(host, 'hold', [p.id for p in live if p.host == host])
        for process in live:
            if process.id not in self._acknowledged:
                self.send(process.host, 'start', process.request)

    def close(self) -> None:
        """Stop holding (the agents end what is left) and destroy the node."""
        self._running = False
        self._thread.join(timeout=5.0)
        self._executor.remove_node(self._node)
        self._node.destroy_node()
        self._executor.shutdown(timeout_sec=0)

"""The host agent (paper §4.4: "models can be deployed in different ways"): composites on several
machines, started over DDS, without ssh.

One agent runs on every machine that hosts composites (``ros2 run itasc_bringup host_agent
--name NAME``). A parent Composer on another machine asks the agent named by the composite's
``host:`` to start it; the agent starts it as ``--deploy per-composite`` starts a local one (a
:mod:`.host` process, whose parent process is the agent) and reports on it. Two topics per host,
``itasc_msgs/msg/Event`` with a JSON ``detail``:

``/itasc_hosts/<host>/requests`` (parents → agent)
    ``start`` ``{"id", "namespace", "parent_namespace", "spec"}``: resent until the status lists
    ``id``; ``hold`` ``[id, ...]``: every :data:`~.hosts.PERIOD`, the parent is alive and still wants them;
    ``kill`` ``[id, ...]``: end them at once (a composite that cannot stop in order).
``/itasc_hosts/<host>/status`` (agent → parents)
    ``status`` ``{id: {"namespace", "pid", "exit"}}`` every :data:`~.hosts.PERIOD` and on every change;
    ``exit`` is null while the process runs.

A composite no parent has held for :data:`~.hosts.HOLD_TIMEOUT` is killed: its parent is gone, so it can
never be stopped in order and must not outlive it (as a local composite process ends when its
parent process is gone). A parent that hears nothing from the agent for :data:`~.hosts.LOST_AFTER` treats
its composites there as dead processes (Safety), see :mod:`.remote`. The agent ends on SIGINT or
SIGTERM, killing the composites it still runs.

Anyone on the DDS domain can ask an agent to start a composite: only models travel, of entity
kinds registered on the agent's machine, never code.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field

from rclpy.node import Node

from itasc_msgs.msg import Event

from .hosts import AGENT_QOS, HOLD_TIMEOUT, HOST_NAME, PERIOD, requests_topic, status_topic

__all__ = ['HostAgent', 'main', 'DUPLICATE_WAIT']

#: How long a starting agent looks for another agent of its name before it answers [s].
DUPLICATE_WAIT = 1.5


@dataclass
class _Hosted:
    """A composite this agent started."""

    namespace: str
    process: subprocess.Popen
    spec_path: str
    held_at: float = field(default_factory=time.monotonic)
    exit: int | None = None


class HostAgent(Node):
    """Starts the composites placed on host ``host`` and reports on them."""

    def __init__(self, *, host: str) -> None:
        super().__init__('host_agent', namespace=f'/itasc_hosts/{host}')
        self.host = host
        self._hosted: dict[str, _Hosted] = {}
        self._status = self.create_publisher(Event, status_topic(host), AGENT_QOS)
        self._seq = 0
        self.create_subscription(Event, requests_topic(host), self._on_request, AGENT_QOS)
        self.create_timer(PERIOD, self._update)

    def _on_request(self, msg: Event) -> None:
        try:
            request = json.loads(msg.detail)
            if msg.name == 'start':
                self._start(request)
            elif msg.name == 'hold':
                for hosted in map(self._hosted.get, request):
                    if hosted is not None:
                        hosted.held_at = time.monotonic()
            elif msg.name == 'kill':
                for hosted in filter(None, map(self._hosted.get, request)):
                    if hosted.exit is None:
                        hosted.process.kill()
            else:
                raise ValueError(f'unknown request {msg.name!r}')
        except (ValueError, TypeError, KeyError) as err:
            self.get_logger().error(f'refused a request from {msg.source}: {type(err).__name__}: {err}')

    def _start(self, request: dict) -> None:
        if request['id'] in self._hosted:
            return  # a start resent before our status reached the parent
        namespace, parent_namespace = str(request['namespace']), str(request['parent_namespace'])
        fd, path = tempfile.mkstemp(prefix='itasc_remote_', suffix='.json')
        with os.fdopen(fd, 'w') as out:
            json.dump(request['spec'], out)
        command = [sys.executable, '-m', 'itasc_core.composition.host', '--spec', path,
                   '--namespace', namespace, '--parent-namespace', parent_namespace,
                   '--parent-pid', str(os.getpid())]
        process = subprocess.Popen(command, env={**os.environ, 'ITASC_HOST': self.host})
        self._hosted[request['id']] = _Hosted(namespace=namespace, process=process, spec_path=path)
        print(f'host_agent {self.host}: started {namespace} pid {process.pid}', flush=True)
        self._report()

    def _update(self) -> None:
        now = time.monotonic()
        for id_, hosted in list(self._hosted.items()):
            if hosted.exit is None and now - hosted.held_at > HOLD_TIMEOUT:
                print(f'host_agent {self.host}: {hosted.namespace} lost its parent; killed', flush=True)
                hosted.process.kill()
            if hosted.exit is None and hosted.process.poll() is not None:
                hosted.exit = hosted.process.returncode
                _unlink(hosted.spec_path)
                print(f'host_agent {self.host}: {hosted.namespace} ended (exit code {hosted.exit})', flush=True)
            elif hosted.exit is not None and now - hosted.held_at > HOLD_TIMEOUT:
                del self._hosted[id_]  # its end was reported and no parent asks about it any more
        self._report()

    def _report(self) -> None:
        self._seq += 1
        status = {id_: {'namespace': h.namespace, 'pid': h.process.pid, 'exit': h.exit}
                  for id_, h in self._hosted.items()}
        self._status.publish(Event(stamp=self.get_clock().now().to_msg(), source=self.get_fully_qualified_name(),
                                   name='status', seq=self._seq, detail=json.dumps(status)))

    def end(self) -> None:
        """Kill the composites still running (they cannot be stopped in order from here)."""
        for hosted in self._hosted.values():
            if hosted.exit is None:
                hosted.process.kill()
                hosted.exit = hosted.process.wait()
                print(f'host_agent {self.host}: killed {hosted.namespace} on ending', flush=True)
            _unlink(hosted.spec_path)


def _unlink(path: str) -> None:
    try:
        os.unlink(path)
    except OSError:
        pass


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog='host_agent', description='Start the composites placed on this host, as parents on other hosts ask.',
        epilog='DDS: the same ROS_DOMAIN_ID on every machine; ITASC_DDS_PEERS=<every machine\'s address,...> '
               '(and optionally ITASC_DDS_INTERFACES) to discover across machines without multicast.')
    parser.add_argument('--name', default=os.environ.get('ITASC_HOST'),
                        help='this host\'s name, as composites name it in host: (default: $ITASC_HOST)')
    args = parser.parse_args(argv)
    if not args.name or not re.match(HOST_NAME, args.name):
        parser.error(f'--name (or ITASC_HOST) must be a name like arm_pc (letters, digits, _), got {args.name!r}')

    from ..communication.dds import DdsSettingsError, configure_dds
    try:
        configure_dds()
    except DdsSettingsError as err:
        print(f'error: {err}', file=sys.stderr)
        return 2
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    from .deployment import end_process_within, make_executor

    stop: list[int] = []
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda s, _frame: stop.append(s))
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    executor = make_executor()
    agent = HostAgent(host=args.name)
    executor.add_node(agent)
    domain = os.environ.get('ROS_DOMAIN_ID', '0')
    try:
        # two agents of one name would both start every composite placed on that host: look for
        # another before answering (a discovery round: participants announce themselves every 0.5 s)
        until = time.monotonic() + DUPLICATE_WAIT
        while not stop and time.monotonic() < until and agent.count_publishers(status_topic(args.name)) < 2:
            executor.spin_once(timeout_sec=0.05)
        if agent.count_publishers(status_topic(args.name)) > 1:
            print(f'error: a host agent named {args.name} already runs in ROS domain {domain}; give this one '
                  'another --name', file=sys.stderr)
            return 2
        print(f'host_agent {args.name}: ready (ROS_DOMAIN_ID {domain}, pid {os.getpid()})', flush=True)
        while not stop:
            executor.spin_once(timeout_sec=0.05)
    finally:
        agent.end()
        end_process_within()
        executor.remove_node(agent)
        agent.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    raise SystemExit(main())

"""Composites on several machines (issue #11, paper §4.4): two Linux network namespaces joined by
a veth pair stand for two machines, each with its own address on that pair and nothing else. The
host agent runs in one, the bootstrap in the other; they find each other over DDS with unicast
discovery to ``ITASC_DDS_PEERS`` (README "Several machines"). The application is the shipped
``pattern_two_hosts``: its program composite (and the two task composites inside it) is placed on
the host ``second``."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from collections import defaultdict
from pathlib import Path

import pytest
from processes import Spawned
from rosbags.highlevel import AnyReader

AGENT_ADDRESS, BOOTSTRAP_ADDRESS = '10.200.0.1', '10.200.0.2'
PEERS = f'{AGENT_ADDRESS},{BOOTSTRAP_ADDRESS}'


def _ip(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    return subprocess.run(['ip', *args], capture_output=True, text=True, timeout=10, check=check)


@pytest.fixture
def machines():
    """Two network namespaces ("machines") joined by a veth pair: (agent's, bootstrap's) names."""
    if shutil.which('ip') is None:
        pytest.skip('no iproute2 (ip) on this machine: network namespaces cannot be made')
    tag = os.getpid()
    agent, bootstrap = f'itasc{tag}a', f'itasc{tag}b'
    refused = _ip('netns', 'add', agent, check=False)
    if refused.returncode != 0:
        pytest.skip(f'ip netns add refused (needs root or CAP_SYS_ADMIN): {refused.stderr.strip()}')
    try:
        _ip('netns', 'add', bootstrap)
        _ip('link', 'add', f'it{tag}a', 'type', 'veth', 'peer', 'name', f'it{tag}b')
        for ns, end, address in ((agent, f'it{tag}a', AGENT_ADDRESS), (bootstrap, f'it{tag}b', BOOTSTRAP_ADDRESS)):
            _ip('link', 'set', end, 'netns', ns)
            _ip('-n', ns, 'addr', 'add', f'{address}/24', 'dev', end)
            _ip('-n', ns, 'link', 'set', end, 'up')
            _ip('-n', ns, 'link', 'set', 'lo', 'up')
        yield agent, bootstrap
    finally:
        for ns in (agent, bootstrap):
            _ip('netns', 'del', ns, check=False)  # takes its end of the veth pair with it


def _env(address: str) -> dict[str, str]:
    """The environment of one machine: our DDS settings for several machines, the test's domain."""
    env = {k: v for k, v in os.environ.items() if k not in ('FASTRTPS_DEFAULT_PROFILES_FILE',
                                                           'ROS_AUTOMATIC_DISCOVERY_RANGE')}
    return {**env, 'ITASC_DDS_PEERS': PEERS, 'ITASC_DDS_INTERFACES': address}


def _agent(ns: str) -> Spawned:
    agent = Spawned(['ip', 'netns', 'exec', ns, sys.executable, '-m', 'itasc_core.composition.host_agent',
                     '--name', 'second'], env=_env(AGENT_ADDRESS))
    agent.wait_for_line('host_agent second: ready', timeout=30)
    return agent


def _bootstrap(ns: str, *args: str) -> Spawned:
    return Spawned(['ip', 'netns', 'exec', ns, sys.executable, '-m', 'itasc_bringup.bootstrap', 'pattern_two_hosts',
                    *args], env=_env(BOOTSTRAP_ADDRESS))


def _states(bag: Path) -> dict[str, list[tuple[float, str]]]:
    """Per composite state topic: (recorded time [s], state), in order."""
    out: dict[str, list[tuple[float, str]]] = defaultdict(list)
    with AnyReader([bag]) as reader:
        connections = [c for c in reader.connections if c.msgtype == 'itasc_msgs/msg/CoordinatorState']
        for connection, log_time, raw in reader.messages(connections):
            out[connection.topic].append((log_time * 1e-9, reader.deserialize(raw, connection.msgtype).state))
    return out


def _data(bag: Path, topic: str) -> list[float]:
    with AnyReader([bag]) as reader:
        connections = [c for c in reader.connections if c.topic == topic]
        return [reader.deserialize(raw, c.msgtype).data[0] for c, _, raw in reader.messages(connections)]


def _first(states: list[tuple[float, str]], state: str) -> float:
    return next(t for t, s in states if s == state)


def test_a_composite_placed_on_another_host_runs_there_and_stops_in_order(machines, tmp_path):
    agent_ns, bootstrap_ns = machines
    bag = tmp_path / 'run'
    with _agent(agent_ns) as agent:
        with _bootstrap(bootstrap_ns, '--duration', '3', '--record', str(bag)) as app:
            started = agent.wait_for_line('host_agent second: started /app/program pid ', timeout=60)
            pid = started.split()[-1]
            # the program's process lives on the agent's "machine", not where the bootstrap runs
            assert _ip('netns', 'identify', pid).stdout.strip() == agent_ns
            app.wait_for_line('[state] app: Active.Run.Running', timeout=60)
            assert app.finish(timeout=90) == 0, app.output()
        agent.wait_for_line('host_agent second: /app/program ended (exit code 0)', timeout=10)
        agent.send_signal(signal.SIGINT)
        assert agent.finish(timeout=20) == 0, agent.output()
    assert 'app: stopped (duration)' in app.out

    states = _states(bag)
    running = 'Active.Run.Running'
    stopped = 'Active.Stop.Stopped.NotifyStopped'
    for composite in ('/app/program', '/app/program/track', '/app/program/hold'):
        sequence = [s for _, s in states[f'{composite}/state']]
        assert running in sequence and sequence[-1] == stopped, (composite, sequence)
    # in order: the program reaches Running before the root, and stops before the root finishes
    # stopping; its task composites stop before the program cleans up its computation
    app_states, program = states['/app/state'], states['/app/program/state']
    assert _first(program, running) <= _first(app_states, running)
    assert _first(program, stopped) <= _first(app_states, 'Active.Stop.Stopped.CleanupComputation')
    for task in ('track', 'hold'):
        assert _first(states[f'/app/program/{task}/state'], stopped) \
            <= _first(program, 'Active.Stop.Stopped.CleanupComputation')
    # the loop closes across the machines: the program's commands (computed there, from the plant's
    # state sent there) reach the plant here, which follows the sine setpoint of the track task
    commands, plant = _data(bag, '/app/program/mixer/sum'), _data(bag, '/app/plant/state')
    assert len(commands) > 100 and len(plant) > 100
    assert max(plant) - min(plant) > 0.5, (min(plant), max(plant))


def test_a_host_that_drops_off_the_network_puts_the_application_in_safety(machines):
    agent_ns, bootstrap_ns = machines
    with _agent(agent_ns) as agent, _bootstrap(bootstrap_ns) as app:
        app.wait_for_line('[state] app: Active.Run.Running', timeout=60)
        unplugged = time.monotonic()
        _ip('-n', agent_ns, 'link', 'set', f'it{os.getpid()}a', 'down')  # the cable is pulled
        safety = app.wait_for_line('SAFETY:', timeout=15)
        noticed = time.monotonic() - unplugged
        assert "process of composite program is lost: host agent 'second' silent" in safety, safety
        assert noticed < 3.5, f'the lost host was noticed after {noticed:.1f} s'  # LOST_AFTER is 2 s
        # the agent, no longer held by the parent, ends the orphaned composite
        agent.wait_for_line('host_agent second: /app/program lost its parent; killed', timeout=15)
        app.send_signal(signal.SIGINT)
        assert app.finish(timeout=60) == 3, app.output()
        agent.send_signal(signal.SIGINT)
        assert agent.finish(timeout=20) == 0, agent.output()


@pytest.mark.parametrize('env, args, message', [
    ({'ITASC_DDS_PEERS': '10.200.0.1,10.200.0.300'}, ['--name', 'second'],
     "ITASC_DDS_PEERS='10.200.0.1,10.200.0.300': '10.200.0.300' is not an IPv4 address"),
    ({'ITASC_DDS_INTERFACES': 'eth0'}, ['--name', 'second'], "'eth0' is not an IPv4 address"),
    ({}, ['--name', 'arm-pc'], "--name (or ITASC_HOST) must be a name like arm_pc"),
])
def test_the_agent_refuses_bad_settings_with_exit_2(env, args, message):
    base = {k: v for k, v in os.environ.items() if k != 'FASTRTPS_DEFAULT_PROFILES_FILE'}
    with Spawned([sys.executable, '-m', 'itasc_core.composition.host_agent', *args],
                 env={**base, 'ITASC_DDS_PEERS': '10.200.0.1', **env}) as agent:
        assert agent.finish(timeout=30) == 2
    assert message in agent.err and 'Traceback' not in agent.err, agent.err


def test_a_second_agent_of_the_same_name_is_refused_with_exit_2():
    """Two agents named alike both started every composite placed on their host (two copies of one
    composite in one namespace, its events crossing); the second now refuses to start."""
    agent = [sys.executable, '-m', 'itasc_core.composition.host_agent', '--name', 'second']
    with Spawned(agent) as first:
        first.wait_for_line('host_agent second: ready', timeout=30)
        with Spawned(agent) as second:
            assert second.finish(timeout=30) == 2, second.output()
        assert 'error: a host agent named second already runs in ROS domain' in second.err, second.output()
        assert 'ready' not in second.out and 'Traceback' not in second.err, second.output()
        assert first.process.poll() is None  # the first one goes on


def test_the_bootstrap_refuses_a_host_name_the_agent_would_refuse():
    """ITASC_HOST=bad-name was taken silently by the bootstrap (no composite could ever be placed
    there), where the agent refuses the same name."""
    with Spawned([sys.executable, '-m', 'itasc_bringup.bootstrap', 'approach_object', '--duration', '1'],
                 env={**os.environ, 'ITASC_HOST': 'bad-name'}) as app:
        assert app.finish(timeout=30) == 2, app.output()
    assert "ITASC_HOST must be a host name like arm_pc (letters, digits, _), got 'bad-name'" in app.err, app.output()


def test_a_host_without_an_agent_fails_the_start_naming_the_host():
    with Spawned([sys.executable, '-m', 'itasc_bringup.bootstrap', 'pattern_two_hosts', '--duration', '3']) as app:
        assert app.finish(timeout=60) == 2, app.output()
    assert "SAFETY: app entered Safety <- e_emergency from /app/composer: process of composite program could not " \
           "be started: no host agent 'second' answered within 5 s" in app.out, app.output()


def _app_with_hosts(tmp_path: Path, hosts: str) -> Path:
    """A copy of the shipped approach_object application with ``hosts:`` added (YAML text)."""
    from itasc_bringup.apps import resolve_app

    config = tmp_path / 'config'
    shutil.copytree(resolve_app('approach_object').parent.parent, config)
    app = config / 'apps' / 'approach_object.yaml'
    app.write_text(app.read_text().replace('\n  program:', f'\n  hosts: {hosts}\n  program:', 1))
    return app


def test_an_application_places_its_program_and_tasks_on_hosts(tmp_path):
    from itasc_bringup.apps import load_composition

    root = load_composition(str(_app_with_hosts(tmp_path, '{itasc: arm_pc, AvoidObstacle: vision_pc}')))
    program = root.entity('itasc')
    placed = {c.name: c.host for c in program.children}
    assert program.host == 'arm_pc' and root.host is None
    assert placed == {'ApproachObject': None, 'AvoidObstacle': 'vision_pc', 'Retreat': None}


def test_a_host_placement_naming_no_composite_is_refused_with_exit_2(tmp_path):
    app = _app_with_hosts(tmp_path, '{Driver_panda: arm_pc}')
    with Spawned([sys.executable, '-m', 'itasc_bringup.bootstrap', str(app)]) as boot:
        assert boot.finish(timeout=60) == 2
    assert "hosts places 'Driver_panda', which is neither the program nor one of its tasks" in boot.err, boot.err
    assert 'Traceback' not in boot.err

"""The bootstrap as a user runs it (``ros2 run itasc_bringup bootstrap``), in its own process."""

from __future__ import annotations

import re
import subprocess
import sys

import pytest

BOOTSTRAP = [sys.executable, '-m', 'itasc_bringup.bootstrap']


def run(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([*BOOTSTRAP, *args], capture_output=True, text=True, timeout=timeout)


def state_sequences(stdout: str) -> dict[str, list[str]]:
    sequences: dict[str, list[str]] = {}
    for composite, state in re.findall(r'^\[state\] (\w+): (\S+)', stdout, flags=re.M):
        sequences.setdefault(composite, []).append(state)
    return sequences


@pytest.fixture(scope='module')
def single():
    return run('pattern_demo', '--duration', '2')


def test_pattern_demo_runs_and_stops_in_order_with_exit_0(single):
    assert single.returncode == 0, single.stderr
    sequences = state_sequences(single.stdout)
    assert set(sequences) == {'app', 'program', 'track', 'hold'}
    for composite, states in sequences.items():
        assert 'Active.Run.Running' in ''.join(states), composite
        assert states[-1].startswith('Active.Stop.Stopped'), composite
    # the monitor switched the tracking task to high_accuracy_control via the Running sub-FSM
    assert 'Active.Run.Running.precise' in sequences['program']
    assert 'app: stopped (duration)' in single.stdout


def test_same_behaviour_with_one_process_per_composite(single):
    per_composite = run('pattern_demo', '--duration', '2', '--deploy', 'per-composite')
    assert per_composite.returncode == 0, per_composite.stderr
    assert state_sequences(per_composite.stdout) == state_sequences(single.stdout)


def test_sigint_leads_to_an_orderly_stop_and_exit_0():
    process = subprocess.Popen([*BOOTSTRAP, 'pattern_demo'], stdout=subprocess.PIPE, text=True)
    for line in process.stdout:
        if line.startswith('[state] app: Active.Run.Running'):
            break
    process.send_signal(subprocess.signal.SIGINT)
    out, _ = process.communicate(timeout=60)
    assert process.returncode == 0
    assert 'app: stopped (signal SIGINT)' in out
    assert '[state] program: Active.Stop.Stopped.NotifyStopped' in out


def test_unknown_application_exits_2_without_traceback():
    result = run('no_such_app')
    assert result.returncode == 2
    assert result.stderr.startswith('error: no_such_app') and 'pattern_demo' in result.stderr
    assert 'Traceback' not in result.stderr


def test_a_dead_composite_process_puts_its_parent_in_safety_and_the_stop_stays_orderly():
    process = subprocess.Popen([*BOOTSTRAP, 'pattern_demo', '--deploy', 'per-composite', '--duration', '4'],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lines = []
    for line in process.stdout:
        lines.append(line)
        if line.startswith('[state] app: Active.Run.Running'):
            break
    killed = subprocess.run(['pkill', '-9', '-f', 'itasc_core.composition.host .*--namespace /app/program/hold'])
    assert killed.returncode == 0
    out, err = process.communicate(timeout=120)
    lines += out.splitlines(keepends=True)
    assert process.returncode == 0, err[-2000:]
    sequences = state_sequences(''.join(lines))
    assert 'Safety' in sequences['program']
    assert sequences['program'][-1].startswith('Active.Stop.Stopped')
    assert 'process of composite hold died' in err

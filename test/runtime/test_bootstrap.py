"""The bootstrap as a user runs it (``ros2 run itasc_bringup bootstrap``), in its own process."""

from __future__ import annotations

import contextlib
import os
import re
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from processes import Spawned, started_here
from scheduling import needs_fifo

BOOTSTRAP = [sys.executable, '-m', 'itasc_bringup.bootstrap']


def run(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    """The bootstrap with ``-v``: every composite's ``[state]`` lines, not only the root's."""
    return subprocess.run([*BOOTSTRAP, '-v', *args], capture_output=True, text=True, timeout=timeout)


def state_sequences(stdout: str) -> dict[str, list[str]]:
    sequences: dict[str, list[str]] = {}
    for composite, state in re.findall(r'^\[state\] (\w+): (\S+)', stdout, flags=re.M):
        sequences.setdefault(composite, []).append(state)
    return sequences


#: The rate of the runs whose computation is compared between deployments [Hz]. At pattern_demo's
#: own 1 kHz, its four processes per composite do not keep up on a loaded 2-core machine (700-800 Hz
#: with hundreds of ticks dropped; a Task then ticks on a stale setpoint now and then): the
#: per-composite median tracking error was 0.04-0.58 there, above 0.15 in 3 of 6 runs, against 0.05
#: at 250 Hz in every run.
COMPARED_RATE = '250'


@pytest.fixture(scope='module')
def single(tmp_path_factory):
    bag = tmp_path_factory.mktemp('single') / 'run.mcap'
    result = run('pattern_demo', '--duration', '2', '--rate', COMPARED_RATE, '--record', str(bag))
    result.bag = bag
    return result


def tracking_errors(bag) -> np.ndarray:
    """The track task's error (setpoint - plant state), every tick of the recorded run."""
    from rosbags.highlevel import AnyReader
    with AnyReader([bag]) as reader:
        connections = [c for c in reader.connections if c.topic == '/app/program/track/controller/error']
        return np.array([reader.deserialize(raw, c.msgtype).data[0] for c, _, raw in reader.messages(connections)])


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


def test_same_behaviour_with_one_process_per_composite(single, tmp_path):
    bag = tmp_path / 'per_composite.mcap'
    per_composite = run('pattern_demo', '--duration', '2', '--rate', COMPARED_RATE, '--deploy', 'per-composite',
                        '--record', str(bag))
    assert per_composite.returncode == 0, per_composite.stderr
    assert state_sequences(per_composite.stdout) == state_sequences(single.stdout)
    # the same computation: the plant tracks the sine as closely in both deployments. The median
    # error, not the RMS: a stall of this machine (a process not scheduled for 100 ms while the
    # sine moves on) weighs on the RMS of a 2 s run (0.24 once in CI), not on what a tick computes.
    errors = {'single': tracking_errors(single.bag), 'per-composite': tracking_errors(bag)}
    typical = {mode: float(np.median(np.abs(e[len(e) // 4:]))) for mode, e in errors.items()}
    assert all(len(e) > 300 for e in errors.values()), {m: len(e) for m, e in errors.items()}  # 2 s at 250 Hz
    assert all(r < 0.15 for r in typical.values()), typical  # a sine of amplitude 1 tracked to within 15 %


@pytest.mark.parametrize('deploy', ['single', 'per-composite'])
def test_ctrl_c_leads_to_an_orderly_stop_and_exit_0(deploy):
    with Spawned([*BOOTSTRAP, '-v', 'pattern_demo', '--deploy', deploy]) as app:
        app.wait_for_line('[state] app: Active.Run.Running', timeout=120)
        os.killpg(app.process.pid, signal.SIGINT)  # as a terminal's Ctrl-C: to every process of the app
        assert app.finish(timeout=60) == 0, app.output()
    assert 'app: stopped (signal SIGINT)' in app.out
    sequences = state_sequences(app.out)
    for composite in ('app', 'program', 'track', 'hold'):
        assert sequences.get(composite, [''])[-1] == 'Active.Stop.Stopped.NotifyStopped', app.output()


def test_signals_after_the_verdict_leave_its_exit_code():
    """Once the console said how the run ended and with which exit code, more Ctrl-Cs or SIGTERMs
    (an impatient user, a supervisor's second signal) do not change it. Before, one that came while
    the interpreter finalized found the default handler back and the exit status was 130 / 143 after
    "exit 0" was printed."""
    with Spawned([*BOOTSTRAP, 'pattern_demo']) as app:
        app.wait_for_line('[state] app: Active.Run.Running', timeout=120)
        app.process.send_signal(signal.SIGTERM)
        app.wait_for_line('app: stopped (signal SIGTERM) - exit 0', timeout=60)
        while app.process.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                app.process.send_signal(signal.SIGINT)
            time.sleep(0.01)
        assert app.finish(timeout=60) == 0, app.output()


def _runnable_time_of_main_thread(pid: int) -> float:
    """How long process ``pid``'s main thread has wanted a CPU so far [s]: the time it ran plus the
    time it waited in a run queue for one (``/proc/<pid>/task/<pid>/schedstat``). A thread that
    spins wants a CPU all the time, however much of it the machine's other processes take."""
    with open(f'/proc/{pid}/task/{pid}/schedstat') as stat:
        on_cpu, waiting, _ = (int(field) for field in stat.read().split())
    return (on_cpu + waiting) * 1e-9


def test_between_ticks_the_thread_that_ticks_waits_or_spins_as_told():
    """``--between-ticks wait``: the bootstrap's thread waits for each tick, wanting a CPU for the
    ticks only; ``spin``: it polls between ticks and wants its core most of the time (a wait there
    makes the next tick up to a third slower on a virtual machine; what it does not want is the
    executor's zero-timeout polls, which sleep ~60 us each: ~0.75 of the time runnable at 200 Hz).
    Measured as the share of the time the thread ran or waited to run, not as the CPU time it got,
    which depends on what else the machine runs (0.69 of a core once, the other test worker busy)."""
    busy = {}
    for mode in ('wait', 'spin'):
        with Spawned([*BOOTSTRAP, '-v', 'pattern_demo', '--rate', '200', '--between-ticks', mode,
                      '--duration', '4']) as app:
            app.wait_for_line('[state] app: Active.Run.Running', timeout=120)
            time.sleep(0.5)
            runnable, since = _runnable_time_of_main_thread(app.process.pid), time.monotonic()
            time.sleep(2.0)
            busy[mode] = (_runnable_time_of_main_thread(app.process.pid) - runnable) / (time.monotonic() - since)
            assert app.finish(timeout=60) == 0, app.output()
    assert busy['spin'] > 0.5, busy
    assert busy['wait'] < busy['spin'] / 2, busy


#: The bootstrap, with a Ctrl-C arriving while it validates the model (the first second of a start:
#: imports and validation), at a point the test controls.
CTRL_C_WHILE_LOADING = ('import os, signal, sys\n'
                        'from itasc_bringup import bootstrap\n'
                        'load = bootstrap.load\n'
                        'def interrupted(*args):\n'
                        '    os.kill(os.getpid(), signal.SIGINT)\n'
                        '    return load(*args)\n'
                        'bootstrap.load = interrupted\n'
                        'sys.exit(bootstrap.main(sys.argv[1:]))\n')


def test_ctrl_c_before_the_bring_up_stops_it_without_a_traceback():
    """Before, a Ctrl-C in the first second ended the process with a KeyboardInterrupt traceback
    from wherever the imports were."""
    result = subprocess.run([sys.executable, '-c', CTRL_C_WHILE_LOADING, 'pattern_demo', '--duration', '5'],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stdout + result.stderr
    assert result.stdout.strip().splitlines()[-1] == 'app: stopped (signal SIGINT) before the bring-up began - exit 0'
    assert 'Traceback' not in result.stderr and '[state]' not in result.stdout, result.stdout + result.stderr


def test_unknown_application_exits_2_without_traceback():
    result = run('no_such_app')
    assert result.returncode == 2
    assert result.stderr.startswith('error: no_such_app') and 'pattern_demo' in result.stderr
    assert 'Traceback' not in result.stderr


def _host_processes(namespace: str = '') -> list[int]:
    """pids of this test's composite processes (``--deploy per-composite``), all or one's."""
    hosts = started_here(command='itasc_core.composition.host')
    return [pid for pid, line in hosts.items() if not namespace or f'--namespace {namespace} ' in line]


def _wake_ups_of_main_thread(pid: int) -> int:
    """How often process ``pid``'s main thread has gone to sleep and been woken so far."""
    with open(f'/proc/{pid}/task/{pid}/status') as status:
        return int(status.read().split('\nvoluntary_ctxt_switches:')[1].split()[0])


@needs_fifo
@pytest.mark.parametrize('priority, policy', [('50', os.SCHED_FIFO), ('0', os.SCHED_OTHER)])
def test_the_threads_that_tick_wait_for_their_ticks_at_a_real_time_priority(priority, policy):
    """``--thread-priority`` (50 by default, as ros2_control's): while the application runs, the
    bootstrap's thread and every composite process's main thread, which wait for their ticks, run
    under SCHED_FIFO and are woken at once (per composite at 500 Hz on the 2-core VM: the Solver
    stepped at 483-493 Hz with it, 424-477 Hz without); 0 leaves the normal policy."""
    with Spawned([*BOOTSTRAP, '-v', 'pattern_demo', '--deploy', 'per-composite', '--rate', '100',
                  '--thread-priority', priority, '--duration', '4']) as app:
        app.wait_for_line('[state] app: Active.Run.Running', timeout=120)
        time.sleep(0.5)
        policies = {pid: os.sched_getscheduler(pid) for pid in [app.process.pid, *_host_processes()]}
        assert app.finish(timeout=60) == 0, app.output()
    assert len(policies) == 4 and set(policies.values()) == {policy}, policies


@needs_fifo
def test_a_composite_in_safety_ticks_on_at_its_real_time_priority():
    """A composite in Safety goes on ticking (each tick makes its entities safe: a Driver commands
    zero) so its process's main thread keeps SCHED_FIFO; it dropped to the normal policy, and the
    commands that hold the robot still came as late as any other thread let them."""
    with Spawned([*BOOTSTRAP, '-v', 'pattern_demo', '--deploy', 'per-composite', '--rate', '100',
                  '--duration', '6']) as app:
        app.wait_for_line('[state] app: Active.Run.Running', timeout=120)
        program, = _host_processes('/app/program')
        hold, = _host_processes('/app/program/hold')
        os.kill(hold, signal.SIGKILL)
        app.wait_for_line('[state] program: Safety', timeout=30)
        time.sleep(0.5)
        policy = os.sched_getscheduler(program)
        assert app.finish(timeout=120) == 3, app.output()  # 3: the run went through Safety
    assert policy == os.SCHED_FIFO, policy


def test_a_composite_process_sleeps_between_its_ticks():
    """At 10 Hz a composite's process has a few things a second to do (its ticks, their data, the
    host's checks). Before, each Coordinator's update timer woke it 200 times a second besides
    (250-270 wake-ups a second measured, 5 % of a core for each process of the 2-core VM)."""
    with Spawned([*BOOTSTRAP, '-v', 'pattern_demo', '--deploy', 'per-composite', '--rate', '10',
                  '--duration', '5']) as app:
        app.wait_for_line('[state] app: Active.Run.Running', timeout=120)
        time.sleep(0.5)
        hosts = _host_processes()
        assert len(hosts) == 3, hosts  # program, hold, track
        before, since = {pid: _wake_ups_of_main_thread(pid) for pid in hosts}, time.monotonic()
        time.sleep(2.0)
        rates = {pid: (_wake_ups_of_main_thread(pid) - n) / (time.monotonic() - since) for pid, n in before.items()}
        assert app.finish(timeout=60) == 0, app.output()
    assert max(rates.values()) < 100, rates


def test_a_dead_composite_process_puts_its_parent_in_safety_and_the_stop_stays_orderly():
    with Spawned([*BOOTSTRAP, '-v', 'pattern_demo', '--deploy', 'per-composite', '--duration', '4']) as app:
        app.wait_for_line('[state] app: Active.Run.Running', timeout=120)
        hold = _host_processes('/app/program/hold')
        assert len(hold) == 1, hold
        os.kill(hold[0], signal.SIGKILL)
        assert app.finish(timeout=120) == 3, app.output()  # 3: the run went through Safety
    sequences = state_sequences(app.out)
    assert 'Safety' in sequences['program']
    assert sequences['program'][-1].startswith('Active.Stop.Stopped')
    assert 'process of composite hold died' in app.err


def test_a_stop_right_at_running_waits_until_the_bootstrap_heard_of_every_composite():
    """DDS discovers a composite process at times only after the root is Running; a Ctrl-C then
    stopped the hierarchy, and a process that ended 0.5 s after its stop, before this process
    (stalled, on a loaded machine) discovered it, left the status and the recording without any
    of its states: the per-composite Ctrl-C test above failed so in about half of the clean-clone
    CI runs. Here the bootstrap stalls for 2 s during the stop (before: 2 to 5 of 6 runs missed
    track or hold or both)."""
    with Spawned([*BOOTSTRAP, '-v', 'pattern_demo', '--deploy', 'per-composite']) as app:
        app.wait_for_line('[state] app: Active.Run.Running', timeout=120)
        os.killpg(app.process.pid, signal.SIGINT)
        app.wait_for_line('[state] app: Active.Stop.Stopping', timeout=30)
        app.process.send_signal(signal.SIGSTOP)
        time.sleep(2.0)
        app.process.send_signal(signal.SIGCONT)
        assert app.finish(timeout=60) == 0, app.output()
    sequences = state_sequences(app.out)
    for composite in ('app', 'program', 'track', 'hold'):
        assert sequences.get(composite, [''])[-1] == 'Active.Stop.Stopped.NotifyStopped', app.output()
    assert 'no state of composite' not in app.err, app.output()


def test_a_ctrl_c_during_the_bring_up_waits_for_nothing_that_never_started(tmp_path):
    """A Ctrl-C while the root deploys (here: waits for its child's process to listen) stops it
    before any child was told to configure: they never leave the state they were created in, which
    they do not publish, and no tick ran that the visualization could draw. Before, the bootstrap
    waited 3 s for their final states and 10 s for a drawing, then blamed DDS for not discovering
    their processes (15.7 s to exit, 5 warnings)."""
    from itasc_bringup.visualization import FIRST_DRAWING_TIMEOUT
    bag = tmp_path / 'run'
    with Spawned([*BOOTSTRAP, 'approach_object', '--deploy', 'per-composite', '--record', str(bag)]) as app:
        app.wait_for_line('[state] approach_object: Active.Configure.Configuring.DeployEntities', timeout=120)
        app.process.send_signal(signal.SIGINT)
        asked = time.monotonic()
        assert app.finish(timeout=60) == 0, app.output()
        took = time.monotonic() - asked
    assert 'approach_object: stopped (signal SIGINT)' in app.out
    assert 'warning' not in app.err, app.output()
    assert took < FIRST_DRAWING_TIMEOUT, app.output()
    from rosbags.highlevel import AnyReader
    with AnyReader([bag]) as reader:
        states = [reader.deserialize(raw, c.msgtype).state for c, _, raw in reader.messages(
            [c for c in reader.connections if c.topic == '/approach_object/state'])]
    assert states[-1] == 'Active.Stop.Stopped.NotifyStopped', states


def test_a_composite_dying_right_after_running_is_a_fault_while_running_not_a_failed_start():
    """The bootstrap looks at its state between housekeeping passes; a Safety right after the root
    reached Running was taken for a failed start (exit 2, '0.0 s in Running') when the pass that
    noticed Running came after it (seen once in CI). Here a pass comes every second."""
    slow = ('import sys\nfrom itasc_bringup import bootstrap\nbootstrap.HOUSEKEEPING_PERIOD = 1.0\n'
            'sys.exit(bootstrap.main(sys.argv[1:]))\n')
    with Spawned([sys.executable, '-c', slow, '-v', 'pattern_demo', '--deploy', 'per-composite',
                  '--duration', '4']) as app:
        app.wait_for_line('[state] app: Active.Run.Running', timeout=120)
        hold = _host_processes('/app/program/hold')
        assert len(hold) == 1, hold
        os.kill(hold[0], signal.SIGKILL)
        assert app.finish(timeout=120) == 3, app.output()  # 3: the run went through Safety
    assert 'failed to start' not in app.out, app.output()


def test_composite_processes_end_when_the_bootstrap_is_killed():
    with Spawned([*BOOTSTRAP, 'pattern_demo', '--deploy', 'per-composite']) as app:
        app.wait_for_line('[state] app: Active.Run.Running', timeout=120)
        assert len(_host_processes()) == 3  # program, and its tasks track and hold
        app.process.kill()  # SIGKILL: no orderly stop, the composite processes are orphaned
        app.process.wait()
        deadline = time.monotonic() + 10
        while _host_processes() and time.monotonic() < deadline:
            time.sleep(0.1)
        assert _host_processes() == []


@pytest.mark.parametrize('variable, value', [('ITASC_DDS_PEERS', 'not-an-address'), ('ROS_DOMAIN_ID', 'abc'),
                                             ('ROS_DOMAIN_ID', '233')])
def test_wrong_dds_settings_exit_2_without_traceback(variable, value):
    """Before, a ROS_DOMAIN_ID that is not a domain id ended in rcl's RCLError traceback, exit 1."""
    env = {**os.environ, variable: value}
    env.pop('FASTRTPS_DEFAULT_PROFILES_FILE', None)  # our profile, generated from the peers
    result = subprocess.run([*BOOTSTRAP, 'pattern_demo', '--duration', '1'], capture_output=True, text=True,
                            timeout=60, env=env)
    assert result.returncode == 2, result.stdout[-2000:] + result.stderr[-2000:]
    assert f'{variable}={value!r}' in result.stderr and 'Traceback' not in result.stderr, result.stderr[-2000:]


def test_a_stuck_bootstrap_tells_where_it_is_stuck_and_runs_on():
    """A test that waits in vain for a line gets the Python stacks of the bootstrap's threads
    (``kill -USR1``), and the bootstrap runs on: it can still be stopped in order."""
    with Spawned([*BOOTSTRAP, 'pattern_demo']) as app:
        app.wait_for_line('[state] app: Active.Run.Running', timeout=120)
        with pytest.raises(AssertionError) as waited:
            app.wait_for_line('a line the bootstrap never prints', timeout=0.5)
        assert 'most recent call first' in waited.value.args[0], waited.value.args[0]
        assert re.search(r'File ".*bootstrap\.py", line \d+ in main', waited.value.args[0]), waited.value.args[0]
        app.send_signal(signal.SIGINT)
        assert app.finish(timeout=60) == 0, app.output()


def test_a_composite_process_leaves_no_model_file_behind_however_its_parent_ends():
    """The model of a composite process was left in the temporary folder by every parent killed
    with SIGKILL (a bootstrap, a host agent): the process now removes it once it has read it."""
    import pathlib
    with Spawned([*BOOTSTRAP, 'pattern_demo', '--deploy', 'per-composite']) as app:
        app.wait_for_line('[state] app: Active.Run.Running', timeout=120)
        specs = [re.search(r'--spec (\S+)', line).group(1) for line in started_here(command='--spec ').values()]
        assert len(specs) == 3, specs  # program, track, hold
        assert not [spec for spec in specs if pathlib.Path(spec).exists()], specs
        app.process.kill()
        app.process.wait()

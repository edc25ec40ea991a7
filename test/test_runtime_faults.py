"""Faults at run time, measured (issue #8): a composite process killed with SIGKILL is detected by
its parent within 100 ms and the robot is held; a Task process stalled for longer than the Solver's
``remote_rows_age`` holds the robot still until it runs again; a driver that says nothing for longer than its
Driver's ``silent_after`` puts the application in Safety, and not before; an event storm across one composite (10,000
events/s for 10 s by default, ``ITASC_STORM_RATE`` to change it) loses nothing, keeps each source's
order and grows the bootstrap's memory by a bounded amount (test/support/storm.py).

What makes the storm lossless is buffering, not speed (itasc_core.communication.qos, .dds): the
event readers hold a whole storm's backlog, the writers keep every event until acknowledged, and
they send heartbeats every 0.1 s so that a datagram the kernel dropped is asked for again at once.
On a loaded 2-core machine the bootstrap falls behind and catches up after the storm; and the test
process itself may not get the CPU to raise 10,000 events/s (about 50 µs each). The test then
reports a skip with its figures, nothing lost, when its raising thread spent more than a fifth of
the time waiting for a CPU; a storm raised slowly without such waiting fails.
``bench/bench_storm.py`` prints the same figures."""

from __future__ import annotations

import json
import os
import signal
import sys
import time

import numpy as np
import pytest
from model_files import app_with_drivers
from processes import Spawned, started_here
from recordings import read_recording
from storm import storm

BOOTSTRAP = [sys.executable, '-m', 'itasc_bringup.bootstrap']
FAKE_ROS2_CONTROL = [sys.executable, '-m', 'itasc_drivers.fake_ros2_control']
#: events per second of the storm test (``ITASC_STORM_RATE`` overrides it)
STORM_RATE = 10_000


def seconds(stamp) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def _moving_per_composite(app: Spawned, task: str) -> int:
    """Once ``approach_object`` (a process per composite) runs and its robot moves: the pid of the
    process of composite ``task``."""
    app.wait_for_line('[state] approach_object: Active.Run.Running', timeout=120)
    time.sleep(1.0)  # the robot is moving
    hosts = [pid for pid, line in started_here(command='itasc_core.composition.host').items()
             if f'--namespace /approach_object/itasc/{task} ' in line]
    assert len(hosts) == 1, hosts
    return hosts[0]


def test_a_killed_composite_process_is_detected_within_100_ms_and_the_robot_held(tmp_path):
    mcap = tmp_path / 'run.mcap'
    with Spawned([*BOOTSTRAP, 'approach_object', '--deploy', 'per-composite', '--record', str(mcap)]) as app:
        host = _moving_per_composite(app, 'ApproachObject')
        killed_at = time.time()
        os.kill(host, signal.SIGKILL)
        app.wait_for_line('SAFETY:', timeout=10)
        time.sleep(1.0)  # a second of Safety
        os.killpg(app.process.pid, signal.SIGINT)
        assert app.finish(timeout=60) == 3, app.output()
    run = read_recording(mcap)
    died = [m for m in run['/approach_object/itasc/events']
            if m.name == 'e_emergency' and 'process of composite ApproachObject died' in m.detail]
    assert len(died) == 1, [m.detail for m in run['/approach_object/itasc/events'] if m.name == 'e_emergency']
    latency = seconds(died[0].stamp) - killed_at
    assert 0 <= latency < 0.1, f'detected {latency * 1000:.1f} ms after the kill'
    root = run['/approach_object/state']
    safety = next(m._sent for m in root if m.state == 'Safety')
    stopping = next(m._sent for m in root if m.state == 'Active.Stop.Stopping')
    held = [m for m in run['/approach_object/Driver_panda/joint_state'] if safety + 0.05 < m._sent < stopping]
    assert len(held) > 50 and all(not np.any(m.velocity) for m in held)
    assert all(np.array_equal(m.position, held[0].position) for m in held)


def test_a_stalled_task_process_holds_the_robot_still_until_its_rows_come_again(tmp_path):
    """AvoidObstacle's process stopped for 0.6 s (SIGSTOP, as a process starved of CPU is): its rows
    get older than the Solver's ``remote_rows_age`` (0.1 s) and the robot holds still, instead of
    approaching the object without the obstacle's distance in the problem (before: a joint commanded
    at 0.35-0.41 rad/s for ApproachObject alone); once the process runs again, so does the robot."""
    mcap = tmp_path / 'run.mcap'
    with Spawned([*BOOTSTRAP, 'approach_object', '--deploy', 'per-composite', '--record', str(mcap)]) as app:
        host = _moving_per_composite(app, 'AvoidObstacle')
        stopped_at = time.time()
        os.kill(host, signal.SIGSTOP)
        time.sleep(0.6)
        os.kill(host, signal.SIGCONT)
        time.sleep(1.5)
        os.killpg(app.process.pid, signal.SIGINT)
        assert app.finish(timeout=60) == 0, app.output()
    commands = [(m._sent - stopped_at, np.abs(m.velocity).max())
                for m in read_recording(mcap)['/approach_object/itasc/Solver/command']]
    assert max(v for t, v in commands if -0.5 < t < 0) > 1e-3  # moving before
    stalled = [v for t, v in commands if 0.25 < t < 0.55]
    assert len(stalled) > 10 and max(stalled) == 0.0, stalled
    assert max(v for t, v in commands if 0.6 < t < 2.0) > 1e-3  # moving again
    assert 'the rows of AvoidObstacle are older than remote_rows_age (0.1 s): the robot holds still' in app.err


def test_a_run_shorter_than_the_drivers_grace_names_the_driver_that_never_reported(tmp_path):
    """With no driver running, a run that ends before the silent Driver's grace (5 s for its first
    joint state) is over does not go to Safety, and the robot never moved: the end of the run says
    which Driver's data never came, on the console and in the summary, instead of a clean report."""
    summary = tmp_path / 'summary.json'
    with Spawned([*BOOTSTRAP, 'approach_object_ros_driver', '--duration', '2', '--summary-json', str(summary)]) as run:
        assert run.finish(timeout=120) == 0, run.output()
    warning = ('e_Driver_panda_silent_nothing_received from /approach_object_ros_driver/Driver_panda_silent: '
               'nothing came on /approach_object_ros_driver/Driver_panda/joint_state')
    assert warning in run.output(), run.output()
    assert any(w.startswith(warning) for w in json.loads(summary.read_text())['warnings']), summary.read_text()


def test_an_event_storm_loses_nothing_keeps_order_and_memory_bounded(tmp_path):
    rate = int(os.environ.get('ITASC_STORM_RATE', STORM_RATE))
    figures = storm(tmp_path / 'storm.mcap', rate=rate, seconds=10.0)
    print(figures.summary())
    assert figures.exit_code == 0, figures.output
    assert figures.acked, f'not every event reached the readers {figures.acked_after:.0f} s after the storm'
    assert not figures.gaps, figures.gaps[:5]
    assert figures.lost == 0, figures.summary()
    assert figures.order_kept, figures.summary()
    # bounded by the event readers' depth (EVENT_LISTENER_QOS, EVENT_QOS), not by the storm's length
    assert figures.rss_peak_mb - figures.rss_before_mb < 200, figures.summary()
    if figures.send_seconds >= 10.0 * 1.2 and figures.cpu_wait_seconds > 0.2 * figures.send_seconds:
        # the machine, not the application, was too slow: this process could not raise the storm
        pytest.skip(f'the storm could not be raised at {rate}/s on this machine now (nothing was lost, '
                    f'but the rate was not reached): {figures.summary()}')
    assert figures.send_seconds < 10.0 * 1.2, f'the storm could not be raised at {rate}/s: {figures.summary()}'


def test_a_spinning_bootstrap_whose_ticks_fill_the_period_still_takes_in_its_drivers_joint_states():
    """Ticks that never leave time before the next one (asked for at 5 kHz) with ``--between-ticks
    spin``: the thread still serves the executor every 2 ms, so the joint states of a driver in
    another process come in and the robot moves. The loop used to run due ticks back to back and
    serve nothing: the Driver was taken for silent (Safety) at 0.25 s, at 1 kHz too on a loaded machine."""
    with Spawned(FAKE_ROS2_CONTROL), Spawned([*BOOTSTRAP, 'approach_object_ros_driver', '--rate', '5000',
                                               '--between-ticks', 'spin', '--duration', '4']) as run:
        assert run.finish(timeout=120) == 0, run.output()
    assert 'SAFETY' not in run.out and 'Running.approach_accurately' in run.out, run.output()


@pytest.mark.parametrize('silent_after', [None, 3.0])
def test_a_paused_driver_puts_the_application_in_safety_after_the_drivers_silent_after(tmp_path, silent_after):
    """``silent_after`` of a Driver (default 20 periods, at least 0.25 s) is how long its driver may
    say nothing: a driver paused for 1 s stops the application by default, not with 3 s; paused
    for longer than that, it does."""
    fields = {} if silent_after is None else {'silent_after': silent_after}
    app = app_with_drivers('approach_object_ros_driver', tmp_path, **fields)
    # -v: should it stall again on the way to Running (once in a clean-clone CI, unexplained), the
    # output shows the events and every composite's states
    with Spawned(FAKE_ROS2_CONTROL) as driver, Spawned([*BOOTSTRAP, '-v', str(app)]) as run:
        run.wait_for_line('[state] approach_object_ros_driver: Active.Run.Running', timeout=120)
        time.sleep(1.0)
        assert not any(line.startswith('SAFETY') for line in run.forget_lines()), run.output()
        os.kill(driver.process.pid, signal.SIGSTOP)  # the driver says nothing for a second
        time.sleep(1.0)
        os.kill(driver.process.pid, signal.SIGCONT)
        time.sleep(1.0)
        safety = [line for line in run.forget_lines() if line.startswith('SAFETY')]
        if silent_after is None:
            assert safety and 'Driver_panda_silent' in safety[0], run.output()
        else:
            assert not safety, run.output()
            os.kill(driver.process.pid, signal.SIGSTOP)  # now longer than silent_after
            run.wait_for_line('SAFETY: approach_object_ros_driver entered Safety <- e_emergency from '
                              '/approach_object_ros_driver/Driver_panda_silent', timeout=silent_after + 5)
            os.kill(driver.process.pid, signal.SIGCONT)
        os.killpg(run.process.pid, signal.SIGINT)
        run.finish(timeout=60)

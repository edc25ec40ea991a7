"""Ending a run, whatever state it is in (issue #8 "Exits"): SIGINT or SIGTERM during Configure,
Start, Run, Stop or Safety stops the hierarchy in order and leaves a finished recording (exit 0,
or 3 through Safety); SIGKILL of the bootstrap leaves a recording its writer process finishes,
losing at most about the last second, and one whose writer was killed too ``itasc-recover`` makes
readable."""

from __future__ import annotations

import os
import signal
import sys
import time
from pathlib import Path

import pytest
from processes import Spawned, started_here
from rosbags.highlevel import AnyReader

BOOTSTRAP = [sys.executable, '-m', 'itasc_bringup.bootstrap']
RECOVER = [sys.executable, '-m', 'itasc_bringup.recording.recover']
MODELS = Path(__file__).parent / 'data' / 'models'

#: (where, command line after the bootstrap, the line to wait for before the signal, exit code)
MOMENTS = {
    # per-composite: the root waits in Configure while the program's process starts its own
    'Configure': (['-v', 'pattern_demo', '--deploy', 'per-composite'], '[state] program: Active.Configure.Configuring',
                  0),
    'Start': (['pattern_demo', '--deploy', 'per-composite'], '[state] app: Active.Start.Starting', 0),
    'Run': (['pattern_demo'], '[state] app: Active.Run.Running', 0),
    'Stop': (['pattern_demo', '--duration', '0.5'], '[state] app: Active.Stop.Stopping', 0),
    'Safety': ([str(MODELS / 'infeasible.yaml')], 'SAFETY:', 3),
}


def root_states(mcap: Path) -> list[str]:
    with AnyReader([mcap]) as reader:
        root = min((c for c in reader.connections if c.topic.endswith('/state')), key=lambda c: c.topic.count('/'))
        return [reader.deserialize(raw, root.msgtype).state for _, _, raw in reader.messages([root])]


@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
@pytest.mark.parametrize('moment', list(MOMENTS))
def test_a_signal_in_any_state_stops_in_order_with_a_finished_recording(moment, signum, tmp_path):
    args, line, code = MOMENTS[moment]
    mcap = tmp_path / 'run.mcap'
    with Spawned([*BOOTSTRAP, *args, '--record', str(mcap)]) as app:
        app.wait_for_line(line, timeout=120)
        os.killpg(app.process.pid, signum)  # as a terminal's Ctrl-C, or a process manager's stop
        assert app.finish(timeout=60) == code, app.output()
    states = root_states(mcap)  # rosbags reads it: the file is finished
    assert states[-1] == 'Active.Stop.Stopped.NotifyStopped', states[-4:]
    assert 'Active.Stop.Stopping' in states


def _killed_run(mcap: Path, *, writer_too: bool) -> float:
    """pattern_demo recorded into ``mcap`` for a few seconds, then SIGKILL to the bootstrap (and to
    the process writing its recording); returns when the bootstrap was killed (time.time())."""
    with Spawned([*BOOTSTRAP, 'pattern_demo', '--record', str(mcap)]) as app:
        app.wait_for_line('[state] app: Active.Run.Running', timeout=120)
        time.sleep(3.0)  # a run of a few seconds, then the bootstrap dies without a word
        writers = started_here(command='itasc_bringup.recording.writer')
        assert len(writers) == 1, writers
        killed_at = time.time()
        app.process.kill()
        if writer_too:
            os.kill(next(iter(writers)), signal.SIGKILL)
        app.process.wait()
    return killed_at


def test_a_killed_bootstrap_leaves_a_finished_recording(tmp_path):
    """Its writer process finishes the bag once the bootstrap is gone (the pipe to it ends)."""
    mcap = tmp_path / 'run.mcap'
    killed_at = _killed_run(mcap, writer_too=False)
    deadline = time.monotonic() + 30.0
    while started_here(command='itasc_bringup.recording.writer') and time.monotonic() < deadline:
        time.sleep(0.1)
    with AnyReader([mcap]) as reader:  # finished: summary and footer
        log_times = [t for _, t, _ in reader.messages()]
    assert len(log_times) > 1000
    lost = killed_at - max(log_times) * 1e-9
    assert lost < 1.5, f'the last {lost:.2f} s before the kill are lost'


def test_a_recording_whose_writer_was_killed_too_is_made_readable_by_itasc_recover(tmp_path):
    mcap = tmp_path / 'run.mcap'
    killed_at = _killed_run(mcap, writer_too=True)
    with pytest.raises(Exception):  # noqa: B017 - a cut-off MCAP fails with one of several errors
        with AnyReader([mcap]) as reader:
            list(reader.messages())
    with Spawned([*RECOVER, str(mcap), '-o', str(tmp_path / 'recovered.mcap')]) as recover:
        assert recover.finish(timeout=60) == 0, recover.output()
    with AnyReader([tmp_path / 'recovered.mcap']) as reader:
        log_times = [t for _, t, _ in reader.messages()]
    assert len(log_times) > 1000
    lost = killed_at - max(log_times) * 1e-9
    assert lost < 1.5, f'the last {lost:.2f} s before the kill are lost'


def test_a_cut_off_bag_folder_is_named_as_such_by_the_replay_and_recovered_by_its_folder(tmp_path):
    """Before, itasc-replay said only 'not a readable bag (RecordLengthLimitExceeded ...)' and
    itasc-recover said 'no such file' for the folder; the replay now names the way out, and
    itasc-recover takes the folder (its one MCAP file)."""
    bag = tmp_path / 'run'
    _killed_run(bag, writer_too=True)
    mcap = bag / 'run_0.mcap'
    with Spawned([sys.executable, '-m', 'itasc_bringup.replay', str(bag)]) as replay:
        assert replay.finish(timeout=120) == 2, replay.output()
    assert f'{bag}: not a readable bag (' in replay.err, replay.output()
    assert f'itasc-recover {mcap} writes a readable copy of what it holds' in replay.err, replay.output()
    with Spawned([*RECOVER, str(bag)]) as recover:
        assert recover.finish(timeout=60) == 0, recover.output()
    recovered = bag / 'run_0.recovered.mcap'
    assert recover.out.startswith(f'{recovered}: '), recover.output()
    with AnyReader([recovered]) as reader:
        assert sum(1 for _ in reader.messages()) > 1000


def test_a_second_instance_in_the_same_domain_stops_before_anything_starts():
    """The same application started again in the same ROS domain (a second terminal) exits 2 at once,
    naming the running one's process, and the running one goes on untouched to its orderly end
    (``app`` is pattern_demo's root: the namespace both would share).
    Before, the second one ran, and the two took each other's events: the running one's
    Coordinators logged 65 "lost events" (the other's sequence numbers) and its program switched
    back from precise to tracking on the other's Monitor event."""
    with Spawned([*BOOTSTRAP, 'pattern_demo', '--duration', '8']) as first:
        first.wait_for_line('[state] app: Active.Run.Running', timeout=120)
        running = len(first.stdout)  # the lines up to the Running one
        with Spawned([*BOOTSTRAP, 'pattern_demo', '--duration', '2']) as second:
            assert second.finish(timeout=60) == 2, second.output()
        assert f'app already runs in ROS domain {os.environ["ROS_DOMAIN_ID"]} on this machine ' \
               f'(process {first.process.pid})' in second.err, second.output()
        assert first.finish(timeout=60) == 0, first.output()
        after_running = ''.join(first.stdout[running:])
    assert 'Configur' not in after_running and 'Safety' not in after_running, after_running
    assert 'stopped (duration) - exit 0' in after_running, after_running

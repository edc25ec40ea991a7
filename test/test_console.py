"""What a robot programmer reads (issue #15): short plain output ending in a summary whose figures
are the recording's, ``--summary-json`` for scripts, a live view on a terminal that shows Safety,
and ``itasc-plot``'s inequality panel drawn from the recorded distances and bound."""

from __future__ import annotations

import fcntl
import json
import os
import pty
import re
import select
import struct
import subprocess
import sys
import termios
import time
from pathlib import Path

import numpy as np
import pyte
import pytest
import yaml
from rosbags.highlevel import AnyReader

BOOTSTRAP = [sys.executable, '-m', 'itasc_bringup.bootstrap']
REPO = Path(__file__).resolve().parent.parent
MODELS = Path(__file__).parent / 'data' / 'models'
ROOT = '/approach_object'
PROGRAM = f'{ROOT}/itasc'


def recorded(mcap: Path) -> dict[str, list]:
    """topic -> [(log time s, message)] of every message of the recording."""
    topics: dict[str, list] = {}
    with AnyReader([mcap]) as reader:
        for connection, log_time, raw in reader.messages():
            message = reader.deserialize(raw, connection.msgtype)
            topics.setdefault(connection.topic, []).append((log_time * 1e-9, message))
    return topics


def seconds(stamp) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


@pytest.fixture(scope='module')
def approach(tmp_path_factory):
    """``approach_object`` for 10 s, piped (no terminal), recorded, with ``--summary-json``."""
    out = tmp_path_factory.mktemp('console')
    began = time.monotonic()
    result = subprocess.run([*BOOTSTRAP, 'approach_object', '--duration', '10', '--record', str(out / 'run.mcap'),
                             '--summary-json', str(out / 'summary.json')], capture_output=True, text=True, timeout=240)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    result.topics = recorded(out / 'run.mcap')
    result.summary = json.loads((out / 'summary.json').read_text())
    result.out = out
    result.wall = time.monotonic() - began
    return result


def recorded_path(topics: dict) -> list[tuple[str, float]]:
    """The program's Running sub-FSM path, seconds from the first composite in Running."""
    states = [m for topic, items in topics.items() if topic.endswith('/state') for _, m in items
              if hasattr(m, 'composite')]
    start = min(seconds(m.stamp) for m in states if m.state.startswith('Active.Run.Running'))
    return [(m.state.removeprefix('Active.Run.Running.'), seconds(m.stamp) - start)
            for _, m in topics[f'{PROGRAM}/state'] if m.state.startswith('Active.Run.Running.')]


def test_plain_output_is_short_shows_the_path_and_ends_in_the_summary(approach):
    lines = approach.stdout.splitlines()
    assert len(lines) <= 30, approach.stdout
    # the root's phases and the sub-FSM, not every composite's life cycle
    assert not [line for line in lines if re.match(r'\[state\] (AvoidObstacle|Retreat): ', line)], approach.stdout
    for state in ('approach', 'approach_accurately', 'hold'):
        assert f'[state] itasc: Active.Run.Running.{state}  <- ' in approach.stdout
    assert re.fullmatch(r'approach_object: stopped \(duration\) - exit 0, 10\.\d s in Running', lines[-1]), lines[-1]
    path = next(line for line in lines if line.strip().startswith('path'))
    assert re.search(r'itasc: approach 0\.\d\d s -> approach_accurately \d+\.\d\d s -> hold \d+\.\d\d s', path), path
    # the full trace went to the log file the summary names, every composite's every transition
    trace = Path(next(line for line in lines if line.strip().startswith('trace')).split(None, 1)[1])
    assert '[state] AvoidObstacle: Active.Stop.Stopped.NotifyStopped' in trace.read_text()


def test_summary_figures_are_those_of_the_recording(approach):
    topics, summary = approach.topics, approach.summary
    assert summary['exit_code'] == 0 and summary['ended'] == 'duration' and summary['safety'] is None
    # the path and its times
    assert [(s['state'], round(s['at'], 6)) for s in summary['paths']['itasc']] == \
        [(state, round(at, 6)) for state, at in recorded_path(topics)]
    tasks = {t['task']: t for t in summary['tasks']}
    # ApproachObject: the final error is the last one recorded
    approach_states = [m for _, m in topics[f'{PROGRAM}/ApproachObject/Rows/state']]
    assert tasks['ApproachObject']['final_error'] == approach_states[-1].error_norm
    # AvoidObstacle: the minimum margin is the smallest recorded distance less the model's d_min
    d_min = yaml.safe_load((REPO / 'config' / 'tasks' / 'avoid_obstacle.yaml').read_text())['d_min']
    distances = np.array([m.output[0] for _, m in topics[f'{PROGRAM}/AvoidObstacle/Rows/state']])
    avoid = tasks['AvoidObstacle']
    assert avoid['kind'] == 'inequality' and avoid['d_min'] == d_min and avoid['d_max'] is None
    assert avoid['min_margin'] == pytest.approx(distances.min() - d_min, abs=1e-15)
    assert avoid['final_distance'] == distances[-1]
    # the same figures in the lines a person reads
    text = approach.stdout
    assert f'final error {approach_states[-1].error_norm:.4g}' in text
    assert f'min margin {distances.min() - d_min:.4g} m' in text
    # rate and tick times, the recording and how to plot it
    rate = summary['rate']
    assert rate['ticks'] > 500 and 20 < rate['achieved'] <= 110 and 0 < rate['tick_p50'] <= rate['tick_p99']
    # in one process the Solver steps in every tick: its rate, over the same window, is the ticks'
    assert rate['solver_hz'] == pytest.approx(rate['achieved'], rel=0.005), rate
    assert 'the Solver stepped at' not in text
    plot = f'ros2 run itasc_bringup itasc-plot {summary["recording"]}'  # a command that runs: not on PATH
    assert summary['recording'].endswith('run.mcap') and summary['plot_command'] == plot
    assert f'(plot it: {plot})' in text


def test_the_summary_says_how_long_the_bring_up_and_the_whole_start_took(approach):
    """Running ``up_after`` s after the bring-up began and ``process_up_after`` s after the process
    started (its imports and the model's validation too), both within the run as seen from here."""
    up, whole = approach.summary['up_after'], approach.summary['process_up_after']
    assert 0 < up < whole < approach.wall - 10.0, (up, whole, approach.wall)
    assert f'Running {up:.2f} s after the bring-up began ({whole:.2f} s after the process started)' in approach.stdout


def test_the_inequality_plot_is_the_recorded_distance_against_d_min(approach):
    from itasc_bringup.plot import read_run
    from itasc_bringup.task_plot import inequality_traces

    series, types, _ = read_run(approach.out / 'run.mcap')
    traces = {t.task: t for t in inequality_traces(series, types)}
    assert set(traces) == {'AvoidObstacle'}  # ApproachObject and Retreat are equality Tasks
    avoid = traces['AvoidObstacle']
    distances = [m.output[0] for _, m in approach.topics[f'{PROGRAM}/AvoidObstacle/Rows/state']]
    assert avoid.distance.tolist() == distances
    assert avoid.d_min == pytest.approx(0.15, abs=1e-9) and avoid.d_max is None
    # active: the commanded motion lay on the bound, i.e. while the hand slid along d_min
    assert avoid.active.any() and not avoid.active.all()
    assert np.all(avoid.distance[avoid.active] < 0.15 + 0.02)


def _on_a_terminal(args: list[str], *, rows: int, columns: int) -> tuple[subprocess.Popen, int]:
    """``args`` running with a pseudo-terminal of ``rows`` x ``columns`` as stdin, stdout and
    stderr, and the terminal's side to read what it shows. subprocess forks and execs in C: no
    Python runs in the child of this multi-threaded process (pty.fork, as pexpect uses it, may
    deadlock there)."""
    terminal, side = pty.openpty()
    fcntl.ioctl(side, termios.TIOCSWINSZ, struct.pack('HHHH', rows, columns, 0, 0))
    try:
        return subprocess.Popen(args, stdin=side, stdout=side, stderr=side, start_new_session=True), terminal
    finally:
        os.close(side)


def _shown(terminal: int, *, timeout: float) -> bytes | None:
    """What the program wrote to its terminal since the last call (b'' if nothing within
    ``timeout`` s), None once it closed it."""
    if not select.select([terminal], [], [], timeout)[0]:
        return b''
    try:
        return os.read(terminal, 65536) or None
    except OSError:  # EIO: every process holding the terminal has ended
        return None


def test_the_live_view_shows_the_tree_the_tasks_and_safety_in_red():
    screen = pyte.Screen(140, 50)
    stream = pyte.ByteStream(screen)
    child, terminal = _on_a_terminal([*BOOTSTRAP, str(MODELS / 'infeasible.yaml'), '--duration', '8'],
                                     rows=50, columns=140)
    deadline = time.monotonic() + 180
    try:
        running, safety = None, None
        while time.monotonic() < deadline:
            data = _shown(terminal, timeout=1.0)
            if data is None:
                break
            stream.feed(data)
            shown = '\n'.join(screen.display)
            # the children reach Running before their parent: wait for the whole tree
            if (running is None and re.search(r'^infeasible +Run\.Running', shown, flags=re.M)
                    and re.search(r'└── StayClose +Run\.Running', shown) and 'distance 0.' in shown):
                running = shown
            if safety is None and 'SAFETY:' in shown and 'rate - (Safety: nothing runs)' in shown:
                safety = (shown, [row for row in range(screen.lines) if screen.display[row].startswith('SAFETY:')],
                          {row: dict(screen.buffer[row]) for row in range(screen.lines)})
        child.wait(timeout=max(deadline - time.monotonic(), 1.0))
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
        os.close(terminal)
    assert child.returncode == 3, '\n'.join(screen.display)
    assert running is not None, '\n'.join(screen.display)
    # the tree of composites, each with its state, and a row per task
    for line in (r'^infeasible\s+Run\.Running', r'^└── itasc\s+Run\.Running\.\w+\s+path: approach',
                 r'^\s+├── ApproachObject\s+Run\.Running', r'^\s+└── StayClose\s+Run\.Running',
                 r'^ ApproachObject\s+error \d\.\d{4}', r'^ AvoidObstacle\s+distance 0\.\d{4} m, margin '):
        assert re.search(line, running, flags=re.M), (line, running)
    assert re.search(r'^rate \d+\.\d Hz \(target 100\), tick p50', running, flags=re.M), running
    # Safety: said at once, on a red line, with its reason; the view drawn in place, not scrolled
    shown, rows, buffer = safety
    assert rows and 'infeasible problem' in shown, shown
    assert buffer[rows[0]][0].fg == 'red' and buffer[rows[0]][0].bold
    assert re.search(r'path: approach → squeeze', shown), shown
    assert len(re.findall(r'── StayClose', shown)) == 1, shown
    final = '\n'.join(screen.display)
    assert re.search(r'^infeasible: stopped \(duration, went through Safety\) - exit 3', final, flags=re.M), final


def test_help_lists_the_applications_and_examples():
    result = subprocess.run([*BOOTSTRAP, '--help'], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0
    assert re.search(r'applications: .*approach_object.*pattern_demo', result.stdout)
    assert len(re.findall(r'^  bootstrap \w+', result.stdout, flags=re.M)) == 3
    assert 'register-python-argcomplete bootstrap' in result.stdout


def test_shell_completion_offers_the_applications(tmp_path):
    import os
    line = 'bootstrap appr'
    candidates = tmp_path / 'candidates'
    env = {**os.environ, '_ARGCOMPLETE': '1', '_ARGCOMPLETE_IFS': '\n', 'COMP_LINE': line,
           'COMP_POINT': str(len(line)), '_ARGCOMPLETE_STDOUT_FILENAME': str(candidates)}
    result = subprocess.run(BOOTSTRAP, env=env, capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert set(candidates.read_text().split()) == {'approach_object', 'approach_object_ros_driver'}

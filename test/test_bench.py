"""``bench/bench_app.py --json``, the machine-readable figures of issue #9 that other tools read,
for applications other than the one it was written for: several robots, a Driver that talks to an
outside driver (run against the stand-in its kind names), a composition model without a program."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from model_files import two_arms

BENCH_APP = [sys.executable, str(Path(__file__).resolve().parents[1] / 'bench' / 'bench_app.py')]



def bench(*args: str) -> dict:
    # the test's own ROS domain, not the benchmark's: parallel test runs must not hear each other
    env = dict(os.environ, ITASC_BENCH_DOMAIN=os.environ['ROS_DOMAIN_ID'])
    result = subprocess.run([*BENCH_APP, *args, '--json'], capture_output=True, text=True, timeout=300, env=env)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-5000:]
    return json.loads(result.stdout.strip().splitlines()[-1])


def test_two_robots_one_of_them_behind_a_ros2_control_driver(tmp_path):
    """One arm simulated, the other through the ros2_control adapter (a controller name with a
    namespace, its own joint-state and command topics, joints in another order): the Solver solves only once
    every robot reported its joints, so only if the stand-in answered the adapter; the hand-written
    node reads both arms' joint states. Before, the benchmark started no driver for the adapter
    (the program never computed and its tick times were reported all the same) and the hand-written
    node read the first robot only, and failed on a Driver without ``initial``."""
    model = two_arms(tmp_path, name='two_arms', drivers=[
        {'robot': 'other', 'kind': 'ros2_control', 'controller': 'other/velocity_controller',
         'joint_states': '/other/joint_states', 'command_topic': '/other/forward/commands',
         'joints': ['b_j3', 'b_j1', 'b_j2']},
        {'robot': 'arm', 'kind': 'simulated', 'initial': {'j2': 0.3, 'j3': 0.5}}])
    figures = bench('--app', str(model), '--rate', '200', '--seconds', '2')
    assert figures['exit_code'] == 0, figures
    assert figures['ticks'] > 200 and figures['achieved_hz'] > 100, figures
    assert figures['solver_hz'] > 100 and figures['qp_p50_us'] > 0, figures  # the stand-in drove the other arm
    assert figures['solver_p50_us'] > 0 and figures['tick_p50_us'] > 0, figures
    assert figures['solver_paced_p99_us'] >= figures['solver_paced_p50_us'] > 0, figures
    assert figures['handwritten_hz'] > 100 and figures['handwritten_p50_us'] > 0, figures


def test_a_composition_model_has_figures_of_its_own_and_no_baseline():
    """A composition model (``composite:``) has no constraint-based program, so neither a solver
    step nor a hand-written node to compare with: those figures are null, and the JSON says why.
    Before, the benchmark ended with a ModelError traceback."""
    figures = bench('--app', 'pattern_demo', '--rate', '200', '--seconds', '2')
    assert figures['exit_code'] == 0 and figures['achieved_hz'] > 100, figures
    assert figures['solver_p50_us'] is None and figures['handwritten_p50_us'] is None, figures
    assert 'composition model' in figures['baseline'], figures


def test_where_a_tick_goes_times_every_entity_that_ran():
    """``bench/bench_entities.py`` times each scheduled entity inside the application's ticks. A
    Scheduler runs a list of what is switched on that it keeps in step with its items; the benchmark
    wrapped the items only, so nothing it timed ever ran and every entity was listed as switched off."""
    script = Path(__file__).resolve().parents[1] / 'bench' / 'bench_entities.py'
    result = subprocess.run([sys.executable, str(script), '--rate', '200', '--seconds', '2'],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-5000:]
    timed = {}
    for line in result.stdout.split('in the application')[1].split('the plain computation')[0].splitlines():
        parts = line.split(maxsplit=1)
        if len(parts) == 2 and parts[0].replace('.', '', 1).isdigit():
            timed[parts[1]] = float(parts[0])
    assert {'itasc/Solver', 'itasc/Scene', 'itasc/ApproachObject/VKC'} <= set(timed), result.stdout
    assert timed['itasc'] > timed['itasc/Solver'] > 0, result.stdout  # a composite includes its children


@pytest.mark.parametrize('script', ['bench_app.py', 'bench_entities.py', 'bench_instructions.py',
                                    'bench_visualization.py'])
def test_a_wrong_model_is_refused_in_one_line_before_anything_runs(tmp_path, script):
    """A benchmark of a model that is wrong says what the bootstrap says (the file, the field) and
    exits 2. Before, it ended in a ModelError traceback (exit 1), or went on to measure."""
    model = tmp_path / 'wrong.yaml'
    model.write_text('application:\n  nme: wrong\n')
    path = Path(__file__).resolve().parents[1] / 'bench' / script
    result = subprocess.run([sys.executable, str(path), '--app', str(model)], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 2, result.stdout[-3000:] + result.stderr[-5000:]
    assert result.stderr.strip() == f'error: {model}: application.name: required field is missing', result.stderr
    assert result.stdout == '', result.stdout

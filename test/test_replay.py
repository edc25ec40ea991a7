"""``itasc-replay``: a recorded run as a regression test. Replaying an unchanged model reproduces
the recorded commands to 1e-9; a changed Solver gain is reported and fails the tolerance; a bag
that is not one is a clear error (exit 2)."""
import re
import shutil
import sys

import pytest
from processes import Spawned

REPLAY = [sys.executable, '-m', 'itasc_bringup.replay']


@pytest.fixture(scope='module')
def recorded(tmp_path_factory):
    bag = tmp_path_factory.mktemp('replay') / 'run'
    with Spawned([sys.executable, '-m', 'itasc_bringup.bootstrap', 'approach_object', '--duration', '3',
                  '--record', str(bag)]) as app:
        assert app.finish(timeout=120) == 0, app.output()
    return bag


def _replay(*args: str) -> tuple[int, str]:
    with Spawned([*REPLAY, *map(str, args)]) as replay:
        code = replay.finish(timeout=120)
        return code, replay.out + replay.err


def _largest(out: str) -> float:
    return float(re.search(r'^largest difference (\S+) rad/s', out, re.M).group(1))


def test_an_unchanged_model_reproduces_the_recorded_commands(recorded):
    code, out = _replay(recorded)
    assert code == 0, out
    ticks = int(re.search(r'Solver: (\d+) ticks replayed', out).group(1))
    assert ticks >= 100, out            # 3 s at 100 Hz, the program moving from about 0.3 s on
    assert _largest(out) <= 1e-9, out


def test_a_changed_solver_gain_is_reported(recorded, tmp_path):
    from itasc_bringup.apps import resolve_app

    config = tmp_path / 'config'
    shutil.copytree(resolve_app('approach_object').parent.parent, config)
    program = config / 'programs' / 'approach_object.yaml'
    text = program.read_text()
    assert 'solver: {kind: qp, backend: daqp}' in text
    program.write_text(text.replace('solver: {kind: qp, backend: daqp}',
                                    'solver: {kind: qp, backend: daqp, joint_weights: {panda_joint1: 20.0}}'))
    code, out = _replay(recorded, '--app', config / 'apps' / 'approach_object.yaml', '--tolerance', '1e-6')
    assert code == 1, out
    assert _largest(out) > 1e-6 and 'BEYOND the tolerance' in out, out
    joint1 = float(re.search(r'panda_joint1\s+largest difference (\S+)', out).group(1))
    assert joint1 > 1e-6, out


def test_a_file_that_is_not_a_bag_is_a_clear_error(tmp_path):
    bad = tmp_path / 'notes.mcap'
    bad.write_text('not a bag')
    code, out = _replay(bad, '--app', 'approach_object')
    assert code == 2, out
    assert 'notes.mcap: not a readable bag' in out and 'Traceback' not in out, out

"""Kinds registered through entry points (issue #10), proven by their effect on a running program:
the task type and the Monitor condition of test/plugins/itasc_test_kinds (a package outside the
source tree, installed by the test set-up), and the project's own point_plane and inside, written
the same way."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

from recordings import read_recording

BOOTSTRAP = [sys.executable, '-m', 'itasc_bringup.bootstrap']
MODELS = Path(__file__).parent / 'data' / 'models'


def _run(model: str, tmp_path: Path, seconds: float) -> dict[str, list]:
    mcap = tmp_path / 'run.mcap'
    result = subprocess.run([*BOOTSTRAP, str(MODELS / model), '--duration', str(seconds), '--record', str(mcap)],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    return read_recording(mcap)


def _running_states(recording: dict[str, list], namespace: str) -> list[str]:
    return [m.state.removeprefix('Active.Run.Running.') for m in recording[f'{namespace}/state']
            if m.state.startswith('Active.Run.Running.')]


def test_a_task_type_and_a_condition_of_another_package_run_in_a_program(tmp_path):
    """horizontal_distance brings the TCP from 19 cm to 8 cm of the target in its xy plane, and near
    moves the Running sub-FSM on once it is there."""
    recording = _run('outside_kinds.yaml', tmp_path, 6.0)
    hover = [m.output[0] for m in recording['/outside_kinds/itasc/Hover/Rows/state']]
    assert hover[0] > 0.15, hover[0]
    assert abs(hover[-1] - 0.08) < 0.002, hover[-1]
    assert _running_states(recording, '/outside_kinds/itasc')[-1] == 'there'
    close = [m for m in recording['/outside_kinds/itasc/events'] if m.name == 'e_close']
    assert len(close) == 1 and 'near' in close[0].detail


def test_a_point_plane_inequality_keeps_the_hand_above_the_table_and_inside_tells_it_is_there(tmp_path):
    """The target is 10 cm below the table top: Reach pulls the TCP down, AboveTable (point_plane,
    d_min 5 cm) stops it 5 cm above the top, where inside ([4.5, 5.5] cm) moves the program to rest."""
    recording = _run('above_the_table.yaml', tmp_path, 6.0)
    height = [m.output[0] for m in recording['/above_the_table/itasc/AboveTable/Rows/state']]
    assert height[0] > 0.2 and min(height) > 0.045, (height[0], min(height))
    reach = recording['/above_the_table/itasc/Reach/Rows/state'][-1]
    assert reach.error_norm > 0.09  # the table is in the way: the target stays 15 cm off
    assert _running_states(recording, '/above_the_table/itasc')[-1] == 'rest'
    assert any(m.name == 'e_on_table' and 'inside' in m.detail for m in recording['/above_the_table/itasc/events'])


def _broken_plugin(site: Path) -> dict[str, str]:
    """An installed distribution (a dist-info on the path) of four controllers that cannot be used,
    and the environment that has it on the path."""
    import os
    package = site / 'broken_kinds'
    package.mkdir(parents=True)
    (package / '__init__.py').write_text('')
    (package / 'syntax.py').write_text('class Controller(\n')
    (package / 'needs.py').write_text('import a_module_nobody_installed\n')
    (package / 'wrong.py').write_text(textwrap.dedent('''\
        from pydantic import Field
        from itasc_tasks.controllers.kind import ConstraintController
        from itasc_core.computation.parameters import ParameterModel
        class NotOne:
            pass
        class NegativeGain(ConstraintController):
            class Parameters(ParameterModel):
                kp: float = Field(default=-5.0, ge=0)
        '''))
    info = site / 'broken_kinds-0.1.dist-info'
    info.mkdir()
    (info / 'METADATA').write_text('Metadata-Version: 2.1\nName: broken_kinds\nVersion: 0.1\n')
    (info / 'entry_points.txt').write_text(textwrap.dedent('''\
        [itasc.controllers]
        broken_syntax = broken_kinds.syntax:Controller
        broken_import = broken_kinds.needs:Controller
        broken_class = broken_kinds.wrong:NotOne
        broken_default = broken_kinds.wrong:NegativeGain
        '''))
    return dict(os.environ, PYTHONPATH=f'{site}{os.pathsep}{os.environ.get("PYTHONPATH", "")}')


def test_a_broken_plugin_stops_only_the_models_that_name_it(tmp_path):
    """An installed plugin whose kind cannot be used (its module does not import, the entry point
    names no controller, a default its own rules refuse) stopped every application with a
    traceback, exit 1, even those that never name it. Now each is said once (not again by the
    application's other processes), the others run, and a model naming one is refused before
    anything starts, with why."""
    env = _broken_plugin(tmp_path / 'site')
    said = {'broken_syntax': "(broken_kinds.syntax:Controller) does not import: SyntaxError",
            'broken_import': "(broken_kinds.needs:Controller) does not import: ModuleNotFoundError",
            'broken_class': '(broken_kinds.wrong:NotOne) is not a ConstraintController',
            'broken_default': '(broken_kinds.wrong:NegativeGain) has defaults its own rules refuse: kp: Input should '
                              'be greater than or equal to 0'}
    # 3 s: long enough for the display process, which loads the same kinds, to have said them again
    result = subprocess.run([*BOOTSTRAP, 'approach_object', '--duration', '3'], capture_output=True, text=True,
                            timeout=120, env=env)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    warnings = [line for line in result.stderr.splitlines() if line.startswith('warning: constraint controller')]
    assert len(warnings) == 4 and 'Traceback' not in result.stderr, result.stderr
    for name, why in said.items():
        assert any(f"'{name}' {why}" in line for line in warnings), (name, warnings)

    model = tmp_path / 'uses_it.yaml'
    model.write_text((MODELS / 'above_the_table.yaml').read_text().replace(
        'controller: {kind: p, kp: 1.5, max_output: 0.2}', 'controller: {kind: broken_default}').replace(
        '../../../config/', f'{MODELS.parents[2]}/config/'))
    result = subprocess.run([*BOOTSTRAP, str(model), '--duration', '0.5'], capture_output=True, text=True,
                            timeout=120, env=env)
    assert result.returncode == 2, result.stdout[-3000:] + result.stderr[-3000:]
    error = result.stderr.strip().splitlines()[-1]
    assert error.startswith(f'error: {model}:') and said['broken_default'] in error, result.stderr
    assert 'Traceback' not in result.stderr

    # a kind that does not exist: the kinds offered instead are those that can be used
    model.write_text(model.read_text().replace('{kind: broken_default}', '{kind: proportional}'))
    result = subprocess.run([*BOOTSTRAP, str(model), '--duration', '0.5'], capture_output=True, text=True,
                            timeout=120, env=env)
    assert result.returncode == 2, result.stdout[-3000:] + result.stderr[-3000:]
    error = result.stderr.strip().splitlines()[-1]
    assert "unknown constraint controller 'proportional'; known: " in error, error
    known = error.rpartition('known: ')[2]
    assert "'p'" in known and 'broken' not in known, error  # the kinds that can be used, not the broken ones

"""Kinds registered through entry points (issue #10), proven by their effect on a running program:
the task type and the Monitor condition of test/plugins/itasc_test_kinds (a package outside the
source tree, installed by the test set-up), and the project's own point_plane and inside, written
the same way."""

from __future__ import annotations

import subprocess
import sys
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

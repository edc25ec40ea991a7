"""The tests' process helper (``test/support/processes.py``): a wait for a line that never comes
fails with where the process is stuck, not only with what it printed."""

from __future__ import annotations

import sys

import pytest
from processes import Spawned


def test_a_wait_that_times_out_names_the_processes_of_the_group_and_their_state():
    program = 'import subprocess, time; subprocess.Popen(["sleep", "30"]); print("up", flush=True); time.sleep(30)'
    with Spawned([sys.executable, '-c', program]) as run:
        run.wait_for_line('up', timeout=30)
        with pytest.raises(AssertionError) as failure:
            run.wait_for_line('never printed', timeout=0.5)
    message = str(failure.value)
    assert "no line 'never printed' within 0.5 s" in message and '--- ps' in message
    group = message.partition('--- ps\n')[2].partition('\n---')[0].splitlines()
    assert group[0].split()[:4] == ['PGID', 'PID', 'PPID', 'STAT'], group
    commands = [line.split(maxsplit=6)[6] for line in group[1:]]
    assert any(c.startswith(sys.executable) for c in commands) and 'sleep 30' in commands, group

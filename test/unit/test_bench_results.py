"""The benchmark report (``bench/results.py``, issue #9): ``make bench`` writes one run's figures
as ``RESULTS.md`` and a picture; the Tasks section says what each added Task cost the bring-up."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / 'bench'))
from results import write_results


def _run(*, rate: float = 100.0, tasks: int | None = None, up: float = 0.5) -> dict:
    return {'achieved_hz': rate, 'rate_hz': rate, 'solver_hz': rate, 'dropped_ticks': 0, 'tick_p50_us': 500.0,
            'tick_p99_us': 900.0, 'qp_p50_us': 150.0, 'bring_up_s': up, 'start_to_running_s': up + 2.0,
            'load_before': 0.5, **({} if tasks is None else {'tasks': tasks})}


def test_the_report_lists_each_program_size_and_the_bring_up_each_added_task_cost(tmp_path):
    results = {'machine': {'date': '2026-11-29T02:46', 'cpu': 'AMD EPYC', 'cores': 2, 'versions': {'python': '3.12'}},
               'rates': [_run(rate=100.0), _run(rate=1000.0)], 'record': None, 'per_composite': None,
               'per_composite_record': None,
               'tasks': [_run(tasks=1, up=0.5), _run(tasks=5, up=0.9), _run(tasks=10, up=1.4)],
               'dof': [], 'reaction': None}
    markdown, picture = tmp_path / 'RESULTS.md', tmp_path / 'results.png'
    write_results(results, markdown=markdown, picture=picture)
    text = markdown.read_text()
    assert all(f'| {n} Tasks |' in text for n in (1, 5, 10)), text
    assert 'Bring-up per added Task (rclpy.init to Running): 1->5: 0.100 s, 5->10: 0.100 s.' in text, text
    assert picture.read_bytes().startswith(b'\x89PNG')

    results['tasks'] = results['tasks'][:1]  # one size: nothing to compare
    write_results(results, markdown=markdown, picture=picture)
    assert 'Bring-up per added Task' not in markdown.read_text()


def test_the_report_has_the_per_composite_runs_with_and_without_a_recording(tmp_path):
    results = {'machine': {'date': '2026-11-29T18:40', 'cpu': 'AMD EPYC', 'cores': 2, 'versions': {'python': '3.12'}},
               'rates': [_run(rate=1000.0)], 'record': None, 'per_composite': _run(rate=500.0),
               'per_composite_record': {**_run(rate=500.0), 'achieved_hz': 477.6, 'solver_hz': 388.1},
               'tasks': [], 'dof': [], 'reaction': None}
    markdown, picture = tmp_path / 'RESULTS.md', tmp_path / 'results.png'
    write_results(results, markdown=markdown, picture=picture)
    section = markdown.read_text().split('## approach_object, `--deploy per-composite`')[1]
    rows = [line for line in section.splitlines() if line.startswith('| 500 Hz')]
    assert [row.split('|')[1].strip() for row in rows] == ['500 Hz', '500 Hz `--record`'], section
    assert '477.6' in rows[1] and '388.1' in rows[1], rows

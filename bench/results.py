"""``bench/RESULTS.md`` and ``bench/results.png`` from one run of ``bench_app.py`` (issue #9)."""

from __future__ import annotations

import pathlib

__all__ = ['write_results']


def _us(value) -> str:
    return '-' if value is None else f'{value:.0f}'


def _s(value) -> str:
    return '-' if value is None else f'{value:.2f}'


def _ratio(value) -> str:
    return '-' if value is None else f'{value:.2f}'


def _row(what: str, r: dict) -> str:
    solver_hz = r.get('solver_hz')
    return (f"| {what} | {r['achieved_hz']:.1f} | {'-' if solver_hz is None else f'{solver_hz:.1f}'} | "
            f"{r.get('dropped_ticks', '-')} | {_us(r['tick_p50_us'])} | {_us(r['tick_p99_us'])} | "
            f"{_us(r.get('qp_p50_us'))} | {_us(r.get('solver_p50_us'))} | {_ratio(r.get('tick_over_solver'))} | "
            f"{_us(r.get('solver_paced_p50_us'))} | {_ratio(r.get('tick_over_solver_paced'))} | "
            f"{_us(r.get('solver_paced_p99_us'))} | "
            f"{_us(r.get('handwritten_p50_us'))} | {_ratio(r.get('tick_over_handwritten'))} | "
            f"{_us(r.get('handwritten_p99_us'))} | "
            f"{_s(r.get('bring_up_s'))} | {_s(r.get('start_to_running_s'))} | {r['load_before']:.1f} |")


HEADER = ('| run | achieved Hz | Solver Hz | ticks dropped | tick p50 µs | tick p99 µs | QP p50 µs (in the app) | '
          'solver step p50 µs | tick / solver step | solver step paced p50 µs | tick / paced step | '
          'solver step paced p99 µs | hand-written p50 µs | tick / hand-written | hand-written p99 µs | '
          'up after s (rclpy.init) | up after s (process start) | load |\n|' + '---|' * 18)


def _growth(tasks: list[dict]) -> str:
    """What each added Task cost the bring-up, between the sizes measured ('' for fewer than two)."""
    sizes = [r for r in tasks if r.get('bring_up_s') is not None]
    steps = [f"{a['tasks']}->{b['tasks']}: {(b['bring_up_s'] - a['bring_up_s']) / (b['tasks'] - a['tasks']):.3f} s"
             for a, b in zip(sizes, sizes[1:])]
    if not steps:
        return ''
    return ('Bring-up per added Task (rclpy.init to Running): ' + ', '.join(steps) + '. Fast DDS matches every new '
            'endpoint of a process with every endpoint of the other kind it holds, so what an endpoint costs grows '
            'with the endpoints before it (`bench/bench_endpoints.py`); most of a Task composite\'s endpoints are the '
            'services every composite offers (its Configurator\'s parameter services, its Coordinator\'s operator '
            'services).')


def write_results(results: dict, *, markdown: pathlib.Path, picture: pathlib.Path) -> None:
    m = results['machine']
    lines = [
        '# Benchmark results (issue #9)',
        '',
        f"Written by `make bench` (`python bench/bench_app.py`) on {m['date']}: {m['cpu']}, {m['cores']} cores; "
        + ', '.join(f'{k} {v}' for k, v in m['versions'].items()) + '. The load column is the 1-minute load '
        'average when the run started: these machines are shared, so the ratios measured in one run matter more '
        'than the absolute times.',
        '',
        'Every application run goes through the bootstrap (`python -m itasc_bringup.bootstrap APP --rate HZ '
        '--duration S`, console and visualization included). *Solver step*: the Scene update, every active Task\'s '
        'rows and the QP on the same problem, as one plain computation (`bench/fused.py`), timed in the same run: '
        'back to back, and *paced* at the requested rate, one step a period with a sleep in between, as a control '
        'loop runs (on these VMs a step after a pause of a period takes up to twice as long as one right after '
        'another). '
        '*Hand-written*: one rclpy node reading `joint_states` from a simulated driver in another process, running '
        'that same step and publishing the command (`bench/handwritten.py`), same run. '
        '*Solver Hz*: the Solver\'s steps a second while Running (with `--deploy per-composite` the program runs '
        'in a process of its own, triggered by the root\'s Timer); *ticks dropped*: ticks the Timer dropped, more '
        'than 5 periods behind (it runs the others late, at once).',
        '',
        f"![tick time and rate against the requested rate; bring-up and tick time against the number of Tasks]"
        f"({picture.name})",
        '',
        '## approach_object, `--deploy single`',
        '',
        HEADER,
    ]
    for r in results['rates']:
        lines.append(_row(f"{r['rate_hz']:g} Hz", r))
    if results.get('record'):
        lines.append(_row(f"{results['record']['rate_hz']:g} Hz `--record`", results['record']))
    per_composite = [(f"{r['rate_hz']:g} Hz{label}", r) for label, r in (
        ('', results.get('per_composite')), (' `--record`', results.get('per_composite_record'))) if r]
    if per_composite:
        lines += ['', '## approach_object, `--deploy per-composite`', '', HEADER]
        lines += [_row(what, r) for what, r in per_composite]
    if results.get('tasks'):
        lines += ['', f"## Number of Tasks (Panda, 7 DOF, {results['tasks'][0]['rate_hz']:g} Hz)", '', HEADER]
        lines += [_row(f"{r['tasks']} Tasks", r) for r in results['tasks']]
        if growth := _growth(results['tasks']):
            lines += ['', growth]
    if results.get('dof'):
        lines += ['', '## Degrees of freedom (5 Tasks)', '', HEADER]
        lines += [_row(r['robot'], r) for r in results['dof']]
    reaction = results.get('reaction')
    if reaction:
        lines += ['', '## Reaction to a Monitor', '',
                  f"approach_object at {reaction['rate_hz']:g} Hz: the Monitor `{reaction['monitor']}` raised its "
                  f"event in tick {reaction['raised_in_tick']}; the new gains were used from tick "
                  f"{reaction['first_tick_with_new_gains']} ({reaction['raised_to_applied_ms']:.2f} ms after the "
                  "raise); "
                  f"the Driver acted on them **{reaction['reaction_ticks']} ticks** after the condition became true "
                  '(`bench/reaction.py`).']
    markdown.write_text('\n'.join(lines) + '\n')
    _picture(results, picture)


def _picture(results: dict, path: pathlib.Path) -> None:
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fig, (left, right) = plt.subplots(1, 2, figsize=(12, 4.5))
    rates = results['rates']
    requested = [r['rate_hz'] for r in rates]
    left.plot(requested, [r['tick_p50_us'] for r in rates], 'o-', label='tick p50')
    left.plot(requested, [r['tick_p99_us'] for r in rates], 's--', label='tick p99')
    if all('solver_p50_us' in r for r in rates):
        left.plot(requested, [r['solver_p50_us'] for r in rates], '^:', label='solver step alone p50')
    if all('solver_paced_p50_us' in r for r in rates):
        left.plot(requested, [r['solver_paced_p50_us'] for r in rates], '<:', label='solver step paced p50')
    if all('handwritten_p50_us' in r for r in rates):
        left.plot(requested, [r['handwritten_p50_us'] for r in rates], 'v:', label='hand-written node p50')
    left.set_xlabel('requested rate [Hz]')
    left.set_ylabel('time [µs]')
    left.set_title('approach_object, --deploy single')
    left.legend(loc='upper left')
    achieved = left.twinx()
    achieved.plot(requested, [r['achieved_hz'] for r in rates], 'k*-', label='achieved rate')
    achieved.plot(requested, requested, color='0.7', linewidth=0.8)
    achieved.set_ylabel('achieved rate [Hz]')
    achieved.legend(loc='lower right')
    tasks = results.get('tasks') or []
    if tasks:
        n = [r['tasks'] for r in tasks]
        right.plot(n, [r['bring_up_s'] or 0.0 for r in tasks], 'o-', label='up after [s] (rclpy.init)')
        right.plot(n, [r['start_to_running_s'] or 0.0 for r in tasks], 's--', label='up after [s] (process start)')
        right.set_xlabel('number of Tasks')
        right.set_ylabel('bring-up [s]')
        right.legend(loc='upper left')
        tick = right.twinx()
        tick.plot(n, [r['tick_p50_us'] / 1e3 for r in tasks], 'k^:', label='tick p50 [ms]')
        tick.set_ylabel('tick p50 [ms]')
        tick.legend(loc='lower right')
        right.set_title(f"Panda, {tasks[0]['rate_hz']:g} Hz")
    fig.tight_layout()
    fig.savefig(path, dpi=110)

"""Benchmark of the Composition Pattern runtime (issue: runtime performance).

A 3-level hierarchy (root { program { 3 task composites x 3 FEs }, plant }: 10 Functional
Entities, 5 composites) deployed in one process (``--deploy single``), ticked by the Timer at
1 kHz. Prints the bring-up time (rclpy.init to every Coordinator in Running), the achieved rate
and the tick-to-completion latency (median, p90, p99, max) over the measurement window.
With ``--app NAME`` the same figures for a shipped application (e.g. approach_object: the whole
iTaSC program and its Driver every tick). What TF, markers and diagnostics cost the tick:
``bench_visualization.py``.

    python bench/bench_runtime.py [--rate 1000] [--seconds 10] [--repeat 3] [--app NAME]
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time


def model(rate: float) -> dict:
    def task(name: str) -> dict:
        return {
            'name': name,
            'entities': [
                {'name': 'setpoint', 'kind': 'SineSource'},
                {'name': 'controller', 'kind': 'PController'},
                {'name': 'limit', 'kind': 'PController', 'parameters': {'semantics': 'Velocity(x)'}},
            ],
            'connections': [{'from': 'setpoint.signal', 'to': 'controller.setpoint'},
                            {'from': 'controller.command', 'to': 'limit.setpoint'}],
            'exports': {'command': 'limit.command', 'measured': 'controller.measured'},
        }
    tasks = [task(f'T{i}') for i in range(3)]
    return {
        'name': 'bench', 'rate': rate,
        'entities': [
            {'name': 'program', 'entities': [*tasks, {'name': 'mixer', 'kind': 'Sum'}],
             'connections': [{'from': f'T{i}.command', 'to': 'mixer.inputs'} for i in range(3)],
             'exports': {'command': 'mixer.sum', **{f'm{i}': f'T{i}.measured' for i in range(3)}}},
            {'name': 'plant', 'kind': 'Integrator'},
        ],
        'connections': [{'from': 'program.command', 'to': 'plant.rate'},
                        *({'from': 'plant.state', 'to': f'program.m{i}'} for i in range(3))],
    }


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


def run_once(rate: float, seconds: float, app: str | None = None) -> dict:
    from itasc_core.communication.dds import configure_dds
    configure_dds()
    start = time.monotonic()

    from inprocess import run_application
    from itasc_core.composition.model import CompositeModel

    if app is None:
        spec = CompositeModel.model_validate(model(rate))
    else:
        from itasc_bringup.apps import load_composition
        spec = load_composition(app).model_copy(update={'rate': rate})
    running = run_application(spec, poll=0.001)
    executor, composer = running.executor, running.composer
    bring_up_time = time.monotonic() - start
    composer.timer.durations.clear()
    composer.timer.stamps.clear()
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.01)
    durations = [d * 1e6 for d in composer.timer.durations]
    result = {
        'bring_up_s': bring_up_time,
        'rate_hz': composer.timer.achieved_rate(),
        'median_us': statistics.median(durations),
        'p90_us': percentile(durations, 0.90),
        'p99_us': percentile(durations, 0.99),
        'max_us': max(durations),
        'ticks': len(durations),
    }
    running.stop()
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--rate', type=float, default=1000.0)
    parser.add_argument('--seconds', type=float, default=10.0)
    parser.add_argument('--repeat', type=int, default=3)
    parser.add_argument('--app', default=None, help='a shipped application instead of the synthetic hierarchy')
    args = parser.parse_args()
    cpu = next((line.split(':', 1)[1].strip() for line in open('/proc/cpuinfo') if line.startswith('model name')),
               platform.processor())
    print(f'machine: {cpu}, {os.cpu_count()} cores, Python {platform.python_version()}')
    what = args.app or 'hierarchy: 5 composites, 10 functional entities'
    print(f'{what}, --deploy single, Timer at {args.rate:.0f} Hz')
    print(f'{"run":>3} {"bring-up s":>10} {"rate Hz":>8} {"median us":>9} {"p90 us":>7} {"p99 us":>7} '
          f'{"max us":>7} {"ticks":>6}')
    results = []
    for i in range(args.repeat):
        r = run_once(args.rate, args.seconds, args.app)
        results.append(r)
        print(f'{i:>3} {r["bring_up_s"]:>10.3f} {r["rate_hz"]:>8.1f} {r["median_us"]:>9.0f} {r["p90_us"]:>7.0f} '
              f'{r["p99_us"]:>7.0f} {r["max_us"]:>7.0f} {r["ticks"]:>6}')
    for key in ('bring_up_s', 'rate_hz', 'median_us', 'p99_us'):
        print(f'median over runs: {key} = {statistics.median(r[key] for r in results):.3f}')


if __name__ == '__main__':
    main()

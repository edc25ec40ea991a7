"""Where a tick's time goes (issue #9: "profile first, fix where the time goes"): every scheduled
Functional Entity, child composite and Monitor of an application, timed inside its own ticks, next
to the same program's plain computation (:mod:`fused`: Scene update, each active Task's rows, the
QP) timed in the same process right after. Both halves run on the same machine minutes apart at
most; on these shared VMs only such side-by-side figures compare (the plain step alone varied
170-370 us within ten minutes here).

The application is brought up in this process as ``bootstrap --deploy single`` does
(:mod:`inprocess`), without console, visualization or recording.

    python bench/bench_entities.py [--app approach_object] [--rate 1000] [--seconds 8]
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
from collections import defaultdict
from typing import Any, Callable


def _timed(run: Callable[[float], None], costs: list[float]) -> Callable[[float], None]:
    def timed(t: float) -> None:
        start = time.perf_counter()
        run(t)
        costs.append(time.perf_counter() - start)
    return timed


def instrument(composer: Any, costs: dict[str, list[float]], prefix: str = '') -> None:
    """Time every item of ``composer``'s Scheduler (entities and child composites) and Monitor, and
    of its children in this process, into ``costs`` by path."""
    scheduler = composer.scheduler
    for item in scheduler._items:
        item.run = _timed(item.run, costs[prefix + item.name])
    scheduler._runs = scheduler._switched_on()  # what a tick runs: the timed ones
    for monitor in scheduler._monitors:
        monitor.update = _timed(monitor.update, costs[f'{prefix}monitor {monitor.entity_name}'])
    for name, child in composer.children.items():
        if child is not None:
            instrument(child, costs, f'{prefix}{name}/')


def plain_parts(app: str, *, steps: int, dt: float) -> dict[str, float]:
    """Median seconds of each part of the program's plain step (closed loop, ``steps`` steps)."""
    from fused import FusedProgram
    from itasc_bringup.apps import resolve_app
    from itasc_bringup.model import load_application

    program = FusedProgram.of(load_application(resolve_app(app)))
    scene, q = program.scene, program.initial.copy()
    parts: dict[str, list[float]] = defaultdict(list)
    for k in range(steps):
        t = k * dt
        start = time.perf_counter()
        scene.set_position_vector(q)
        scene.update(t)
        parts['Scene update'].append(time.perf_counter() - start)
        rows = []
        for task in program.tasks:
            began = time.perf_counter()
            rows.append(task.compute(scene, t, dt))
            parts[f'Task {task.name} (relation, chain, setpoint, control, rows)'].append(time.perf_counter() - began)
        began = time.perf_counter()
        result = program.solver.solve(rows, q=scene.q, lower=scene.lower, upper=scene.upper,
                                      velocity_limit=scene.velocity_limit, dt=dt)
        parts['solve'].append(time.perf_counter() - began)
        parts['the whole step'].append(time.perf_counter() - start)
        scene.integrate(result.qdot, dt)
        q = scene.q.copy()
    return {name: statistics.median(values[steps // 5:]) for name, values in parts.items()}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--app', default='approach_object')
    parser.add_argument('--rate', type=float, default=1000.0)
    parser.add_argument('--seconds', type=float, default=8.0)
    args = parser.parse_args()
    os.environ.setdefault('ROS_DOMAIN_ID', str(102 + os.getpid() % 100))
    from bench_app import model_error
    error = model_error(args.app)
    if error is not None:
        print(error, file=sys.stderr)
        return 2

    from inprocess import run_application, spin_for
    from itasc_bringup.apps import load_composition
    from itasc_core.communication.dds import configure_dds

    configure_dds()
    running = run_application(load_composition(args.app).model_copy(update={'rate': args.rate}), poll=0.001)
    costs: dict[str, list[float]] = defaultdict(list)
    try:
        instrument(running.composer, costs)
        spin_for(running.executor, args.seconds)
        timer = running.composer.timer
        ticks = sorted(timer.durations)
        rate = timer.achieved_rate()
    finally:
        running.stop()
    plain = plain_parts(args.app, steps=4000, dt=1.0 / args.rate)

    print(f'{args.app} at {args.rate:g} Hz, {args.seconds:g} s; {platform.node()}, {os.cpu_count()} cores, '
          f'load average {os.getloadavg()[0]:.2f}')
    print(f'tick p50 {ticks[len(ticks) // 2] * 1e6:.0f} us, p99 {ticks[int(len(ticks) * 0.99)] * 1e6:.0f} us, '
          f'achieved {rate:.0f} Hz')
    print('\nin the application (median us a tick; a composite includes its children):')
    ran = {name: statistics.median(values) for name, values in costs.items() if values}
    for name, value in sorted(ran.items(), key=lambda kv: -kv[1]):
        print(f'{value * 1e6:9.1f}  {name}')
    idle = sorted(name for name in costs if name not in ran)
    if idle:
        print(f'     (not run: switched off) {", ".join(idle)}')
    print('\nthe plain computation of the same program (median us a step):')
    for name, value in plain.items():
        print(f'{value * 1e6:9.1f}  {name}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())

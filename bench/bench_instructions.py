"""The cost of a tick in instructions, not in time (issue #9): for telling a change of a few percent
on a shared virtual machine.

On the 2-core VMs these benchmarks run on, the wall time of one build's ticks swings by a quarter
between two runs a minute apart (in-process, back to back: medians 410-720 us for the same code),
so a change that saves 5 % cannot be seen in ``bench_app.py``'s figures, nor in ten of its runs.
The number of instructions the ticks execute does not depend on the machine's load: counted by
valgrind's callgrind, two runs of one build differ by 0.05 %.

What is counted: an application brought up in this process as ``bootstrap --deploy single`` does
(:mod:`inprocess`), then ``--ticks`` ticks of its root Scheduler with the Coordinators' pass after
each (what the Timer's tick runs), at program times ``k / rate``, so the program takes the same
path in every run; only the main thread, and only inside the counted loop (callgrind collects
inside ``functools.reduce``, which runs the loop). With ``--solver``, the same for the solver step
alone (:mod:`fused`: the Scene update, the active Tasks' rows and the solve, as ``bench_app.py``
times it), so the tick's share above the computation is a ratio of two exact counts.

    python bench/bench_instructions.py [--app approach_object] [--ticks 300] [--solver] [--json]

Instructions are not time: a cache miss costs no instruction (on these VMs a tick after a pause runs
up to 1.5x longer for the same instructions, see ``bench_app.py``). Use it to compare two builds,
and ``bench_app.py`` for what the application achieves. Needs ``valgrind`` (skipped without it);
a run takes 1-2 minutes (the bring-up under valgrind).
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from bench_app import _domain, model_error  # noqa: E402 - the benchmarks' ROS domain (ITASC_BENCH_DOMAIN)

#: Ticks run before counting (the first ones build caches and specialise the interpreter).
WARM_UP = 100


def _count_ticks(app: str, *, ticks: int, rate: float) -> None:
    """Child: bring ``app`` up in this process, then run the counted ticks (in ``functools.reduce``)."""
    from inprocess import run_application

    from itasc_bringup.apps import load_composition
    from itasc_core.communication.dds import configure_dds
    configure_dds()
    running = run_application(load_composition(app).model_copy(update={'rate': rate}), poll=0.001)
    timer = running.composer.timer
    timer._timer.cancel()  # the loop below ticks, at program times of its own
    scheduler, after_tick = timer._scheduler, timer._after_tick

    def tick(_, k: int) -> None:
        scheduler.tick(k / rate)
        if after_tick is not None:
            after_tick()
    for k in range(WARM_UP):
        tick(None, k)
    functools.reduce(tick, range(WARM_UP, WARM_UP + ticks), None)
    os._exit(0)  # no stop: the hierarchy's stop is not what is measured, and valgrind makes it slow


def _count_solver(app: str, *, ticks: int, rate: float) -> None:
    """Child: the solver step alone on ``app``'s problem, as ``bench_app.py`` times it."""
    from fused import FusedProgram

    from itasc_bringup.apps import resolve_app
    from itasc_bringup.model import load_application
    program = FusedProgram.of(load_application(resolve_app(app)))
    scene, dt = program.scene, 1.0 / rate
    q = program.initial.copy()

    def closed_loop(_, k: int) -> None:
        nonlocal q
        qdot = program.step(q, k * dt, dt)
        scene.integrate(qdot, dt)
        q = scene.q.copy()
    for k in range(WARM_UP):
        closed_loop(None, k)
    functools.reduce(closed_loop, range(WARM_UP, WARM_UP + ticks), None)
    os._exit(0)


def count(app: str, *, ticks: int, rate: float, solver: bool = False) -> int:
    """Instructions of ``ticks`` counted ticks (or solver steps) of ``app`` under callgrind."""
    with tempfile.TemporaryDirectory() as tmp:
        command = ['valgrind', '--tool=callgrind', '--toggle-collect=functools_reduce',
                   f'--callgrind-out-file={Path(tmp) / "callgrind.out"}', sys.executable, __file__,
                   '--child', 'solver' if solver else 'ticks', '--app', app, '--ticks', str(ticks),
                   '--rate', str(rate)]
        env = dict(os.environ, ROS_DOMAIN_ID=str(_domain()))
        out = subprocess.run(command, capture_output=True, text=True, env=env, timeout=1800)
    collected = re.search(r'Collected : (\d+)', out.stderr)
    if out.returncode != 0 or collected is None:
        raise RuntimeError(f'callgrind run failed (exit {out.returncode}):\n{out.stderr[-3000:]}')
    return int(collected.group(1))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--app', default='approach_object')
    parser.add_argument('--ticks', type=int, default=300)
    parser.add_argument('--rate', type=float, default=1000.0, help='program time advances 1/rate a tick')
    parser.add_argument('--solver', action='store_true', help='also count the solver step alone')
    parser.add_argument('--json', action='store_true')
    parser.add_argument('--child', choices=('ticks', 'solver'), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child == 'ticks':
        _count_ticks(args.app, ticks=args.ticks, rate=args.rate)
    elif args.child == 'solver':
        _count_solver(args.app, ticks=args.ticks, rate=args.rate)
    error = model_error(args.app)
    if error is not None:
        print(error, file=sys.stderr)
        return 2
    if shutil.which('valgrind') is None:
        print('bench_instructions: valgrind not found, skipped (apt install valgrind)')
        return 0
    with ThreadPoolExecutor() as pool:  # the two counts side by side (valgrind runs one thread at a time)
        ticks = pool.submit(count, args.app, ticks=args.ticks, rate=args.rate)
        solver = pool.submit(count, args.app, ticks=args.ticks, rate=args.rate, solver=True) if args.solver else None
        figures: dict = {'app': args.app, 'ticks': args.ticks, 'rate_hz': args.rate,
                         'tick_instructions': ticks.result() / args.ticks}
        if solver is not None:
            figures['solver_instructions'] = solver.result() / args.ticks
            figures['tick_over_solver'] = figures['tick_instructions'] / figures['solver_instructions']
    if args.json:
        print(json.dumps(figures))
    else:
        line = f"{args.app}: {figures['tick_instructions'] / 1e6:.3f} M instructions a tick"
        if args.solver:
            line += (f", the solver step alone {figures['solver_instructions'] / 1e6:.3f} M"
                     f" (x{figures['tick_over_solver']:.2f})")
        print(line + f' ({args.ticks} ticks at program rate {args.rate:g} Hz, callgrind, main thread)')
    return 0


if __name__ == '__main__':
    sys.exit(main())

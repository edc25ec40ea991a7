"""Run-time re-composition benchmark (paper §3.1; issue #14 item 2: "no tick is delayed by more than
one period while a step runs"): how late the ticks of a running application come while
composition steps run, against the ticks of the same run while none does.

The application is pick_and_retreat (bootstrap, its own process, recorded), as a composition model
with steps that can run again and again: the program removes AvoidObstacle and adds it back (a Task
composite built off the tick path, through its life-cycle), swaps its Solver (QP <-> WDLS), and
ApproachObject swaps its controller (PID <-> P). A client in this process runs them in turn through
``~/compose``, as ``ros2 service call`` would. From the recording: the tick times (the Solver's
stamps are the Timer's), and for each step the largest gap between two ticks from the request to
the answer (plus two periods), in periods.

Run: python bench/bench_recompose.py [--rounds 5] [--rate 100] [--deploy single|per-composite]
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

STEPS = [('itasc', 'alone'), ('itasc', 'back'), ('itasc/ApproachObject', 'soft'), ('itasc/ApproachObject', 'stiff'),
         ('itasc', 'least_squares'), ('itasc', 'quadratic')]


def as_kind(entity: dict, registry, kind: str, **changes) -> dict:
    """``entity`` (a composition model's) made of another registered ``kind``: the fields only its
    old kind has left out, the rest kept, ``changes`` applied."""
    params = entity['parameters']
    old, new = registry[params['kind']].Parameters.model_fields, registry[kind].Parameters.model_fields
    kept = {key: value for key, value in params.items() if key not in old or key in new}
    return {**entity, 'parameters': kept | {'kind': kind, **changes}}


def model(directory: Path) -> Path:
    """pick_and_retreat's composition model with steps that undo each other (±inf written ±1e300)."""
    from itasc_bringup.apps import load_composition, write_composition
    from itasc_core.itasc.solver.kind import SOLVERS
    from itasc_tasks.controllers import CONTROLLERS

    data = load_composition('pick_and_retreat').model_dump(by_alias=True, exclude_defaults=True)
    program = next(e for e in data['entities'] if e['name'] == 'itasc')
    avoid = next(e for e in program['entities'] if e['name'] == 'AvoidObstacle')
    solver = next(e for e in program['entities'] if e['name'] == 'Solver')
    task = next(e for e in program['entities'] if e['name'] == 'ApproachObject')
    controller = next(e for e in task['entities'] if e['name'] == 'CC')
    connections = [c for c in program['connections'] if 'AvoidObstacle' in (c['from'] + c['to'])]
    program['composition_steps'] = {
        'alone': {'remove': ['AvoidObstacle']},
        'back': {'add': [avoid], 'connections': connections},
        'least_squares': {'swap': [as_kind(solver, SOLVERS, 'wdls')]},
        'quadratic': {'swap': [solver]}}
    task['composition_steps'] = {
        'soft': {'swap': [as_kind(controller, CONTROLLERS, 'p', kp=1.0)]},
        'stiff': {'swap': [controller]}}
    return write_composition(data, directory / 'pick_and_retreat.yaml')


def compose(node, executor, service: str, step: str, timeout: float = 60.0):
    from itasc_msgs.srv import Compose
    client = node.create_client(Compose, service)
    try:
        deadline = time.monotonic() + timeout
        while not client.service_is_ready():
            if time.monotonic() > deadline:
                raise TimeoutError(service)
            executor.spin_once(timeout_sec=0.05)
        future = client.call_async(Compose.Request(step=step))
        executor.spin_until_future_complete(future, timeout_sec=timeout)
        answer = future.result()
        if answer is None:
            raise TimeoutError(f'{service}: step {step!r} not answered within {timeout:.0f} s')
        return answer
    finally:
        node.destroy_client(client)


def _per_mille(gaps: np.ndarray) -> float:
    return 1000.0 * float((gaps > 2.0).sum()) / max(len(gaps), 1)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--rounds', type=int, default=5)
    parser.add_argument('--rate', type=float, default=100.0)
    parser.add_argument('--deploy', choices=['single', 'per-composite'], default='single')
    args = parser.parse_args()

    from itasc_core.communication.dds import configure_dds
    os.environ.setdefault('ROS_DOMAIN_ID', str(60 + os.getpid() % 30))
    configure_dds()
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / 'test' / 'support'))
    from recordings import read_recording

    with tempfile.TemporaryDirectory() as tmp:
        bag = Path(tmp) / 'run.mcap'
        app = subprocess.Popen([sys.executable, '-m', 'itasc_bringup.bootstrap', str(model(Path(tmp))),
                                '--rate', str(args.rate), '--deploy', args.deploy, '--record', str(bag), '-v'],
                               stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        for line in app.stdout:
            if line.startswith('[state] itasc: Active.Run.Running.wait_for_gripper'):
                break
        # keep reading what the bootstrap prints (-v): a full pipe would stop it in the middle of a step
        threading.Thread(target=lambda: app.stdout.read(), daemon=True).start()
        rclpy.init()
        node = rclpy.create_node('bench_recompose')
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        asked: list[tuple[str, float, float, bool]] = []
        for _ in range(args.rounds):
            for composite, step in STEPS:
                start = time.time()
                answer = compose(node, executor, f'/pick_and_retreat/{composite}/coordinator/compose', step)
                asked.append((step, start, time.time(), answer.success))
                time.sleep(0.3)
        app.send_signal(2)
        app.communicate(timeout=120)
        node.destroy_node()
        rclpy.shutdown()
        run = read_recording(bag, '/pick_and_retreat/itasc/Solver/status')

    status = run['/pick_and_retreat/itasc/Solver/status']
    t = np.array([m.stamp.sec + m.stamp.nanosec * 1e-9 for m in status])
    sent = np.array([m._sent for m in status])
    period = 1.0 / args.rate
    gaps = np.diff(t) / period
    during = np.zeros(len(gaps), dtype=bool)
    print(f'pick_and_retreat, {args.rate:g} Hz, --deploy {args.deploy}, {args.rounds} rounds; '
          f'{platform.node()}, {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f} at the end')
    print(f'{"step":<15}{"ok":>4}{"answer ms":>11}{"ticks":>7}{"max gap [periods]":>19}')
    by_step: dict[str, list[float]] = {}
    for step, start, end, ok in asked:
        window = (sent[1:] >= start) & (sent[1:] <= end + 2 * period)
        during |= window
        worst = float(gaps[window].max()) if window.any() else float('nan')
        by_step.setdefault(step, []).append(worst)
        print(f'{step:<15}{"yes" if ok else "NO":>4}{(end - start) * 1e3:>11.1f}{int(window.sum()):>7}{worst:>19.2f}')
    outside = gaps[~during]
    print(f'gaps between two ticks [periods]: while a step runs p50 {np.median(gaps[during]):.2f} '
          f'p99 {np.percentile(gaps[during], 99):.2f} max {gaps[during].max():.2f}; '
          f'otherwise p50 {np.median(outside):.2f} p99 {np.percentile(outside, 99):.2f} max {outside.max():.2f}')
    late = {step: sum(g > 2.0 for g in worst) for step, worst in by_step.items()}
    print('steps during which a tick came more than one period late:', late)
    # the machine's own lateness is the baseline: a step adds what it has beyond it
    print(f'ticks more than one period late, per 1000: while a step runs {_per_mille(gaps[during]):.2f} '
          f'({int(during.sum())} ticks), otherwise {_per_mille(outside):.2f} ({len(outside)} ticks)')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())

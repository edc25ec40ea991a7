"""Soak benchmark (issue #8): a long run of approach_object whose target moves.

``bench/models/approach_sensed.yaml`` is approach_object with the target ``sensed`` through a
PoseSensor on ``/soak/target_pose``. This script runs it through the bootstrap (recorded), streams
the target's pose at 10 Hz and moves it to the next of four places every ``--retarget`` seconds,
for ``--minutes`` minutes, and prints:

* the bootstrap process's resident memory at 1 min and at the end (growth must stay under 5 %);
* events lost: ``lost events`` lines of the Coordinators, and gaps in the per-source sequence
  numbers of every event in the recording;
* Safety: ``e_emergency`` events and Safety states in the recording (none expected), exit code;
* the tick rate (overall, per minute, longest gap between two Solver ticks) and how many
  retargets the hand followed (ApproachObject's error below 1 mm before the next move; each
  move takes the Running sub-FSM hold -> follow -> hold, with a configuration each way).

    python bench/bench_soak.py [--minutes 10] [--retarget 5] [--out DIR]

Exit code 0 when every criterion holds, 1 otherwise. Not part of ``make test``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

MODEL = Path(__file__).resolve().parent / 'models' / 'approach_sensed.yaml'
APP = 'approach_sensed'
TOPIC = '/soak/target_pose'
#: Where the target goes in turn (x, y, z in the world; the target keeps its orientation).
PLACES = [(0.55, 0.15, 0.20), (0.50, 0.25, 0.25), (0.60, 0.05, 0.25), (0.48, 0.12, 0.15)]
MAX_GROWTH = 5.0  # per cent, RSS at the end over RSS at 1 min


def rss_kib(pid: int) -> int | None:
    try:
        with open(f'/proc/{pid}/status') as status:
            return next(int(line.split()[1]) for line in status if line.startswith('VmRSS:'))
    except (OSError, StopIteration):
        return None


def drive(process: subprocess.Popen, stdout: Path, args: argparse.Namespace) -> dict:
    """Stream the target pose until the bootstrap ends; sample its RSS every 5 s after Running."""
    import rclpy
    from geometry_msgs.msg import PoseStamped
    from rclpy.signals import SignalHandlerOptions

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('soak_target')
    publisher = node.create_publisher(PoseStamped, TOPIC, 10)
    running_at, samples, moves = None, [], []
    place, last_sample = 0, 0.0
    try:
        while process.poll() is None:
            now = time.monotonic()
            if running_at is None and f'{APP}: Active.Run.Running' in stdout.read_text(errors='replace'):
                running_at = now
            if running_at is not None:
                due = int((now - running_at) // args.retarget)
                if due + 1 > len(moves):
                    moves.append(time.time())
                    place = due % len(PLACES)
                if now - last_sample >= 5.0:
                    last_sample = now
                    samples.append((now - running_at, rss_kib(process.pid)))
            msg = PoseStamped()
            msg.header.frame_id = 'world'
            msg.header.stamp = node.get_clock().now().to_msg()
            msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = PLACES[place]
            msg.pose.orientation.w = 1.0
            publisher.publish(msg)
            time.sleep(0.1)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return {'samples': [s for s in samples if s[1] is not None], 'moves': moves}


def read_recording(bag: Path) -> dict[str, list]:
    """(log time [s], message) per kind: events by topic, states, Solver status, task states."""
    from rosbags.highlevel import AnyReader

    kinds = {'itasc_msgs/msg/Event': 'events', 'itasc_msgs/msg/CoordinatorState': 'states',
             'itasc_msgs/msg/SolverStatus': 'solver', 'itasc_msgs/msg/TaskState': 'tasks'}
    found: dict[str, list] = defaultdict(list)
    with AnyReader([bag]) as reader:
        wanted = [c for c in reader.connections if c.msgtype in kinds]
        for connection, stamp, raw in reader.messages(connections=wanted):
            msg = reader.deserialize(raw, connection.msgtype)
            found[kinds[connection.msgtype]].append((stamp * 1e-9, connection.topic, msg))
    return found


def sequence_gaps(events: list) -> list[str]:
    """Per (topic, source): every jump in seq other than +1 (seq 1 starts a new incarnation)."""
    last: dict[tuple[str, str], int] = {}
    gaps = []
    for _, topic, msg in events:
        key = (topic, msg.source)
        if key in last and msg.seq != 1 and msg.seq != last[key] + 1:
            gaps.append(f'{msg.source} on {topic}: #{last[key]} -> #{msg.seq}')
        last[key] = msg.seq
    return gaps


def followed(tasks: list, moves: list[float]) -> tuple[int, int]:
    """How many target moves ApproachObject converged on (error < 1 mm) before the next one."""
    errors = [(t, msg.error_norm) for t, _, msg in tasks if msg.task == 'ApproachObject']
    ends = moves[1:] + [errors[-1][0] if errors else 0.0]
    done = sum(any(start <= t < end and e < 1e-3 for t, e in errors) for start, end in zip(moves, ends))
    return done, len(moves)


def tick_rates(solver: list) -> tuple[list[float], float]:
    """Solver ticks per second in each minute of the run, and the longest gap between two ticks."""
    times = [t for t, _, _ in solver]
    if len(times) < 2:
        return [], 0.0
    start = times[0]
    per_minute: dict[int, int] = defaultdict(int)
    for t in times:
        per_minute[int((t - start) // 60)] += 1
    full = [per_minute[m] / 60.0 for m in sorted(per_minute) if (m + 1) * 60 <= times[-1] - start]
    return full, max(b - a for a, b in zip(times, times[1:]))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--minutes', type=float, default=10.0)
    parser.add_argument('--retarget', type=float, default=5.0, help='seconds between target moves')
    parser.add_argument('--out', type=Path, default=None, help='folder for the recording and logs (default: temp)')
    args = parser.parse_args()
    out = args.out or Path(tempfile.mkdtemp(prefix='soak_'))
    out.mkdir(parents=True, exist_ok=True)
    cpu = next((line.split(':', 1)[1].strip() for line in open('/proc/cpuinfo') if line.startswith('model name')),
               platform.processor())
    print(f'machine: {cpu}, {os.cpu_count()} cores, Python {platform.python_version()}')
    print(f'{APP}: {args.minutes:g} min in Running, target moved every {args.retarget:g} s; output in {out}')
    stdout, stderr = out / 'bootstrap.out', out / 'bootstrap.err'
    command = [sys.executable, '-m', 'itasc_bringup.bootstrap', str(MODEL), '--duration', str(args.minutes * 60),
               '--record', str(out / 'bag'), '--summary-json', str(out / 'summary.json'), '-v']
    with open(stdout, 'w') as o, open(stderr, 'w') as e:
        process = subprocess.Popen(command, stdout=o, stderr=e)
        try:
            driven = drive(process, stdout, args)
            code = process.wait(timeout=120)
        finally:
            if process.poll() is None:
                process.kill()
    summary = json.loads((out / 'summary.json').read_text()) if (out / 'summary.json').exists() else {}
    logs = stdout.read_text(errors='replace') + stderr.read_text(errors='replace')
    recording = read_recording(out / 'bag')

    samples = driven['samples']
    at_1min = next((rss for t, rss in samples if t >= 60.0), None)
    at_end = samples[-1][1] if samples else None
    growth = 100.0 * (at_end - at_1min) / at_1min if at_1min and at_end else float('nan')
    lost_lines = [line for line in logs.splitlines() if 'lost events' in line]
    gaps = sequence_gaps(recording['events'])
    emergencies = [m for _, _, m in recording['events'] if m.name == 'e_emergency']
    safety = [(m.composite, m.event) for _, _, m in recording['states'] if m.state.startswith('Safety')]
    per_minute, longest = tick_rates(recording['solver'])
    done, moves = followed(recording['tasks'], driven['moves'])
    path = [m.state.rsplit('.', 1)[-1] for _, _, m in recording['states']
            if m.composite == 'itasc' and m.state.startswith('Active.Run.Running.')]
    cycles = sum(a == 'follow' and b == 'hold' for a, b in zip(path, path[1:]))
    rate = summary.get('rate', {})

    print(f'exit code: {code} ({summary.get("ended")}), {summary.get("running_for", 0):.0f} s in Running')
    print(f'memory (bootstrap RSS): {at_1min and at_1min / 1024:.1f} MiB at 1 min, '
          f'{at_end and at_end / 1024:.1f} MiB at the end: {growth:+.2f} % (limit {MAX_GROWTH:g} %)')
    print('  RSS by minute: ' + ', '.join(f'{t / 60:.0f}:{r / 1024:.1f}' for t, r in samples if int(t) % 60 < 5))
    print(f'events: {len(recording["events"])} recorded, sequence gaps {len(gaps)}, '
          f'"lost events" lines {len(lost_lines)}')
    for line in (gaps + lost_lines)[:10]:
        print(f'  {line}')
    print(f'safety: {len(emergencies)} e_emergency, {len(safety)} Safety entries {safety[:5]}')
    print(f'tick rate: {rate.get("achieved", float("nan")):.1f} Hz (target {rate.get("target")}), '
          f'tick p50 {1e3 * rate.get("tick_p50", float("nan")):.2f} ms, '
          f'p99 {1e3 * rate.get("tick_p99", float("nan")):.2f} ms, '
          f'{rate.get("ticks")} ticks')
    print('  Solver ticks/s per minute: ' + ', '.join(f'{r:.1f}' for r in per_minute)
          + f'; longest gap between ticks {1e3 * longest:.0f} ms')
    print(f'retargets followed (error < 1 mm before the next move): {done} of {moves}; '
          f'Running sub-FSM hold -> follow -> hold cycles: {cycles}')
    ok = (code == 0 and growth < MAX_GROWTH and not gaps and not lost_lines and not emergencies and not safety)
    print('PASS' if ok else 'FAIL')
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())

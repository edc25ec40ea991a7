"""Log call benchmark (paper §6.2: a computation keeps its rate while it reports): what one
``logger.warning`` costs the thread that calls it, with rclpy's own call-site lookup (``inspect``)
and with :mod:`itasc_core.communication.call_sites` (installed by every entity).

Each configuration runs in a fresh process that holds the modules of a composite process (the
bootstrap's imports): the first warning of the process, then the median of 200 throttled ones
(rclpy finds the call site of a throttled call too, before its filter drops it).

Run: python bench/bench_logging.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys

CHILD = r'''
import json, statistics, sys, time, rclpy
import itasc_bringup.bootstrap  # the modules a composite process holds
from itasc_core.communication import call_sites
if sys.argv[1] == 'call_sites':
    call_sites.install()
rclpy.init()
logger = rclpy.create_node('bench_logging').get_logger()
start = time.perf_counter()
logger.warning('the first line of this process')
first = time.perf_counter() - start
later = []
for _ in range(200):
    start = time.perf_counter()
    logger.warning('a line dropped by its throttle', throttle_duration_sec=60.0)
    later.append(time.perf_counter() - start)
print(json.dumps({'first_ms': first * 1e3, 'later_ms': statistics.median(later) * 1e3}))
'''


def run(mode: str) -> dict:
    out = subprocess.run([sys.executable, '-c', CHILD, mode], capture_output=True, text=True, check=True)
    return json.loads(out.stdout.splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--repeat', type=int, default=3, help='fresh processes per configuration (alternating)')
    args = parser.parse_args()
    print(f'machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, '
          f'python {platform.python_version()}')
    results: dict[str, list[dict]] = {'rclpy': [], 'call_sites': []}
    for _ in range(args.repeat):
        for mode, runs in results.items():
            runs.append(run(mode))
    for mode, runs in results.items():
        print(f"{mode:>10}: first warning {statistics.median(r['first_ms'] for r in runs):.2f} ms, "
              f"a later one {statistics.median(r['later_ms'] for r in runs):.3f} ms "
              f"(medians of {len(runs)} processes)")


if __name__ == '__main__':
    main()

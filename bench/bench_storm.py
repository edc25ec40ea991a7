"""Event storm benchmark (issue #8 item 6): ``pattern_demo`` (1 kHz, recorded) takes a storm of
events on its program composite's event topic, ``--rate`` per second for ``--seconds`` s (default
10,000/s for 10 s), raised by this process from two sources; printed per run: events sent, how long
raising them took and how much of it the raising thread waited for a CPU, when every reader had
acknowledged them, events recorded and lost, whether each source's order was kept, the bootstrap's
resident memory before, at its peak and after, the datagrams the kernel dropped at the bootstrap's
sockets (repaired by DDS), and the machine's load average.

The same storm as ``test/test_runtime_faults.py`` (``test/support/storm.py``).

    python bench/bench_storm.py [--rate 10000] [--seconds 10] [--repeat 1]

Exit code 0 when every run lost nothing and kept the order, 1 otherwise.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / 'test' / 'support'))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--rate', type=int, default=10_000)
    parser.add_argument('--seconds', type=float, default=10.0)
    parser.add_argument('--repeat', type=int, default=1)
    args = parser.parse_args()
    os.environ.setdefault('ROS_DOMAIN_ID', str(150 + os.getpid() % 50))
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    from itasc_core.communication.dds import configure_dds
    configure_dds()
    from storm import storm

    print(f'machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, '
          f'Python {platform.python_version()}')
    ok = True
    for run in range(args.repeat):
        with tempfile.TemporaryDirectory() as folder:
            figures = storm(Path(folder) / 'storm.mcap', rate=args.rate, seconds=args.seconds)
        print(f'run {run + 1}: {figures.summary()}; exit code {figures.exit_code}')
        ok = ok and figures.lost == 0 and figures.order_kept and not figures.gaps
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())

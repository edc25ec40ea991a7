"""What an endpoint costs to create as a process holds more of them (issue #9: bring-up of a
program of 50 Tasks grows faster than the number of Tasks).

Creates, in one rclpy context (one DDS participant, as one process of ours has), batches of
endpoints on distinct topics and prints the cost per endpoint of each batch, as the participant
holds more of them:

* publishers alone, subscriptions alone: flat;
* services (each a request reader and a reply writer), and publishers and subscriptions in turn:
  growing. A new reader costs more the more writers the participant holds, and a new writer the
  more readers, whatever their topics (Fast DDS matches local endpoints pairwise, it seems), so
  creation costs grow with readers x writers: a program whose every entity offers rclpy's six
  parameter services (a reader and a writer each) deploys in time quadratic in its size. Hence
  entities offer none: each composite's Configurator serves its entities' parameters
  (``itasc_core.configuration.parameter_service``); and the entities of a process share one
  ``/rosout`` and one ``/parameter_events`` writer (``itasc_core.communication.process_writers``).

Here (2-core VM, 2026-11-27): publishers 0.37-0.41 ms each over 1200, subscriptions 0.41-0.54,
services 0.63 -> 2.18 ms each from the first 300 to the fourth; publishers and subscriptions in
turn 0.33 -> 1.24 ms.

    python bench/bench_endpoints.py [--batches 4] [--per-batch 300]
"""

from __future__ import annotations

import argparse
import os
import time

__all__ = ['main']


def _cost(create, count: int) -> float:
    """Milliseconds per endpoint over ``count`` calls of ``create()``."""
    t = time.perf_counter()
    for _ in range(count):
        create()
    return (time.perf_counter() - t) / count * 1e3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--batches', type=int, default=4)
    parser.add_argument('--per-batch', type=int, default=300, help='endpoints (services: pairs) per batch')
    args = parser.parse_args()
    os.environ.setdefault('ROS_DOMAIN_ID', str(102 + os.getpid() % 100))  # the tests use 1..101
    from itasc_core.communication.dds import configure_dds
    configure_dds()
    import rclpy
    from rclpy.node import Node
    from std_msgs.msg import Float64
    from std_srvs.srv import Trigger

    def run(kinds: list[str]) -> list[float]:
        """In a participant of its own, batch after batch of endpoints of ``kinds`` in turn: the
        cost per endpoint of each batch."""
        context = rclpy.Context()
        rclpy.init(context=context)
        node = Node('bench_endpoints', context=context, start_parameter_services=False, enable_rosout=False)
        kept: list = []
        make = {
            'publisher': lambda: kept.append(node.create_publisher(Float64, f'/bench/p{len(kept)}', 10)),
            'subscription': lambda: kept.append(
                node.create_subscription(Float64, f'/bench/s{len(kept)}', lambda _: None, 10)),
            'service': lambda: kept.append(node.create_service(Trigger, f'/bench/v{len(kept)}', lambda _, r: r)),
        }
        try:
            return [_cost(make[kind], args.per_batch) for _ in range(args.batches) for kind in kinds]
        finally:
            node.destroy_node()
            rclpy.try_shutdown(context=context)

    print(f'ms per endpoint, batches of {args.per_batch}, each run in a participant of its own')
    for kinds in (['publisher'], ['subscription'], ['service'], ['publisher', 'subscription']):
        figures = run(kinds)
        print(f'{" and ".join(kinds):26s} ' + '  '.join(f'{f:6.2f}' for f in figures), flush=True)


if __name__ == '__main__':
    main()

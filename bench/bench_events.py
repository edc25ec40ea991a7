"""Event delivery benchmark (paper §7.2; issue #8 "event storms"): the CPU a process spends to
raise and to receive one event when N of its entities listen to the composite's event topic, with
the process's event hub (one DDS reader per topic, itasc_core.communication.event_hub) and without
it (one reader per entity, as before the hub).

Each configuration runs in a fresh process (its own ROS domain): N entities listen, a node of the
same process raises 5,000 events, and the process's CPU time is measured for raising them and for
the executor to hand every one to every listener.

Run: python bench/bench_events.py [--listeners 1 5 10 20] [--events 5000] [--repeat 3]
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import subprocess
import sys

CHILD = r'''
import sys, time, rclpy
from rclpy.signals import SignalHandlerOptions
from itasc_core.communication.event_hub import EventHub
from itasc_core.communication.events import EventRaiser
from itasc_core.composition.deployment import Runtime, make_executor
from itasc_core.entity import CompositeContext, Entity

mode, listeners, events = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
if mode == 'reader-per-entity':
    EventHub.of = classmethod(lambda cls, context: None)   # every listener subscribes on its own node
rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
executor = make_executor()
runtime = Runtime(executor=executor, namespace='/bench')
composite = CompositeContext(name='bench', namespace='/bench')
received = [0]
def count(_msg):
    received[0] += 1
for i in range(listeners):
    entity = Entity(f'entity_{i}', composite=composite)
    entity.listen(topics=[composite.events_topic], immediate=True, on_priority=count)
    runtime.add(entity)
source = rclpy.create_node('source', namespace='/bench')
executor.add_node(source)
raiser = EventRaiser(source, topic=composite.events_topic)
start = time.process_time()
for _ in range(events):
    raiser.raise_event('e_bench')
raised = time.process_time()
while received[0] < events * listeners:
    executor.spin_once(timeout_sec=0.05)
done = time.process_time()
print(1e6 * (raised - start) / events, 1e6 * (done - raised) / events)
'''


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--listeners', type=int, nargs='+', default=[1, 5, 10, 20])
    parser.add_argument('--events', type=int, default=5000)
    parser.add_argument('--repeat', type=int, default=3)
    args = parser.parse_args()
    print(f'machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, '
          f'Python {platform.python_version()}; medians of {args.repeat} runs, CPU µs per event')
    print(f'{"listeners":>9} | {"hub: raise":>10} {"receive":>8} | {"reader per entity: raise":>24} {"receive":>8}')
    for n in args.listeners:
        row = []
        for mode in ('hub', 'reader-per-entity'):
            runs = []
            for k in range(args.repeat):
                env = dict(os.environ, ROS_DOMAIN_ID=str(150 + (os.getpid() + k) % 50))
                out = subprocess.run([sys.executable, '-c', CHILD, mode, str(n), str(args.events)],
                                     capture_output=True, text=True, env=env, timeout=600, check=True)
                runs.append([float(x) for x in out.stdout.split()])
            row += [statistics.median(r[0] for r in runs), statistics.median(r[1] for r in runs)]
        print(f'{n:>9} | {row[0]:>10.1f} {row[1]:>8.1f} | {row[2]:>24.1f} {row[3]:>8.1f}')
    return 0


if __name__ == '__main__':
    sys.exit(main())

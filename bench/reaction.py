"""How many ticks a running application takes to act on a Monitor (issue #9, paper Fig. 3).

``approach_object`` runs in this process (``--deploy single``, :mod:`inprocess`) at ``--rate``.
When the Monitor ``tracking_error`` or ``arrived`` raises its event (in tick n0, the tick whose
data made its condition true), the program's Coordinator switches its Running sub-FSM, which
configures ``high_accuracy_control`` in the Task ApproachObject (new controller gains, applied by
the Task's Configurator). The reaction is counted in ticks from n0 to the tick in which the Driver
acts on the first command computed with the new gains: the Constraint Controller computes with
them from the tick after they were applied (n1), the Driver (first in the root's schedule) takes
that command at the start of tick n1 + 1. Ideal: n1 = n0 + 1, a reaction of 2 ticks.

    python bench/reaction.py approach_object --rate 1000     # prints RESULT {json}
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import sys
import time

# the helper of the workspace whose code runs (scripts/env.sh sets ITASC_ROOT)
sys.path.insert(0, str(pathlib.Path(os.environ.get('ITASC_ROOT', pathlib.Path(__file__).resolve().parents[1]))
                       / 'bench'))

MONITORS = ('tracking_error', 'arrived')


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('app', nargs='?', default='approach_object')
    parser.add_argument('--rate', type=float, default=1000.0)
    parser.add_argument('--timeout', type=float, default=30.0)
    args = parser.parse_args()

    from itasc_core.communication.dds import configure_dds
    configure_dds()
    from inprocess import run_application, spin_for
    from itasc_bringup.apps import load_composition

    spec = load_composition(args.app).model_copy(update={'rate': args.rate})
    running = run_application(spec, poll=0.001)
    root = running.composer
    program = next(c for c in root.children.values() if c is not None and c.monitors)
    ticks = root.scheduler
    raised: list[tuple[str, int, float]] = []
    applied: list[tuple[int, float]] = []
    for name in MONITORS:
        monitor = program.monitors[name]
        original = monitor.raise_event

        def raise_event(event, *, original=original, name=name, **kwargs):
            raised.append((name, ticks.ticks, time.monotonic()))
            return original(event, **kwargs)
        monitor.raise_event = raise_event
    cc = program.children['ApproachObject'].entities['CC']
    configure = cc.configure
    gains = (cc.controller.kp, getattr(cc.controller, 'ki', 0.0))

    def configured(params, configure=configure):
        configure(params)
        if (cc.controller.kp, getattr(cc.controller, 'ki', 0.0)) != gains and not applied:
            applied.append((ticks.ticks, time.monotonic()))
    cc.configure = configured
    deadline = time.monotonic() + args.timeout
    while not applied and time.monotonic() < deadline:
        spin_for(running.executor, 0.05)
    running.stop()
    if not applied or not raised:
        print(f'reaction: nothing happened within {args.timeout} s (raised {raised}, applied {applied})',
              file=sys.stderr)
        raise SystemExit(1)
    monitor, n0, raised_at = [r for r in raised if r[1] <= applied[0][0]][-1]
    n_applied, applied_at = applied[0]
    n1 = n_applied + 1  # the first tick computing with the new gains
    print('RESULT ' + json.dumps({
        'monitor': monitor, 'rate_hz': args.rate, 'raised_in_tick': n0, 'first_tick_with_new_gains': n1,
        'reaction_ticks': n1 + 1 - n0, 'raised_to_applied_ms': (applied_at - raised_at) * 1e3}), flush=True)
    os._exit(0)


if __name__ == '__main__':
    main()

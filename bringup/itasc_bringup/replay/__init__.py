"""Replay of a recorded run as a regression test of the application's program (paper §4.2: the
constraint-based program; §6: its life-cycle and Running sub-FSM).

``itasc-replay BAG [--app MODEL] [--tolerance TOL]`` runs the program composite(s) of MODEL
(default: the recorded application) offline, in a ROS domain of its own, on the inputs recorded in
BAG, tick by tick, as fast as it computes (:mod:`.program`). Replayed are the real entities,
configured from MODEL: Robots, Scene, Tasks (VKC, constraint output, setpoint generator,
controller, rows), Solver and Monitors; the Coordinators with their life-cycle and Running sub-FSM,
the Configurators, Schedulers and Composers. Taken from BAG is what came from outside the program:
the Drivers' joint states and the Sensors' poses, the ticks (the stamps ``t`` of
``<program>/Solver/command``) and the events raised to the program from outside it (the root
Coordinator's commands, an operator's, another node's through an ``outside_events`` entity). The
program's own events (a Monitor's, the configuration switches of its Running sub-FSM) are raised
again by the replayed entities, and each is handled as many ticks after it was raised as it was
live (:mod:`.timing`).

At every tick the new commanded joint velocities, every Task's error (``<task>/Rows/state``) and
rows (``<task>/Rows/rows``: what its controller asks of the Solver) are compared with the recorded
ones (:mod:`.compare`); the largest difference per joint and per Task is printed with its tick,
after the path each Running sub-FSM took. Exit code 1 past ``--tolerance``, 0 within it, 2 for a
bag or model that cannot be replayed. An unchanged model reproduces the run to round-off; a changed
gain of a Task's controller or of the Solver, a changed Monitor threshold or Running sub-FSM shows.

Not replayed: the Drivers, the Sensors and the feedback of the new commands through them: the
recorded joint states come whatever the program now commands (open loop), so a changed gain shows
in the commands and rows, while the errors stay those recorded until the program's path departs
from the recorded one. Neither are the root composite's Monitors (driver watchdogs), topics a
setpoint generator reads from outside the program, the wall-clock age that a ``stale`` Monitor
measures, nor calls of a Coordinator's ``~/recover`` and ``~/stop`` services (what they start, the
Coordinator raises itself).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from .recording import ReplayError

if TYPE_CHECKING:
    from .program import Plan, Replayed
    from .recording import Recording

__all__ = ['main', 'replay', 'ReplayError']


def replay(bag: Path, app: str, *, tolerance: float, deploy: str | None = None) -> int:
    """Replay ``bag`` (recorded with ``--deploy deploy``, if known) with the model of ``app`` and
    print the differences; the exit code."""
    from itasc_core.composition.model import walk

    from ..apps import load_composition
    from .program import plan_of, replay_programs
    from .recording import read_recording

    model = load_composition(app)
    plan = plan_of(model)
    states = [f'{path}/state' for program in plan.programs for path, _ in walk(program, plan.root.namespace)]
    recording = read_recording(bag, commands=list(plan.commands.values()), outputs=set(plan.outputs),
                               inputs=set(plan.feeds), events_under=plan.root.namespace + '/', states=set(states))
    if len(recording.ticks) < 2:
        raise ReplayError(f'{bag}: {len(recording.ticks)} tick recorded, nothing to replay')
    ticks = [t * 1e-9 for t in recording.ticks]
    span = ticks[-1] - ticks[0]
    print(f'{bag}: {model.name}, {len(ticks)} ticks from t={ticks[0]:.3f} s to {ticks[-1]:.3f} s ({span:.2f} s)')
    if deploy == 'per-composite':
        print('note: recorded with --deploy per-composite: its composites computed in processes of their own and '
              'their data crossed DDS, at times a tick late; the replay runs the program in one process (as '
              '--deploy single), so it does not reproduce such a run to round-off. For a regression test, record '
              'with --deploy single.')
    replayed = replay_programs(plan, recording)
    print(f'{len(ticks)} ticks replayed in {replayed.seconds:.2f} s ({span / replayed.seconds:.1f}x real time)')
    _print_paths(states, recording, replayed)
    largest = _print_differences(plan, ticks, recording, replayed)
    verdict = 'within' if largest <= tolerance else 'BEYOND'
    print(f'largest difference {largest:.3e}: {verdict} the tolerance {tolerance:g}')
    return 0 if largest <= tolerance else 1


def _print_paths(states: list[str], recording: Recording, replayed: Replayed) -> None:
    """The Running sub-states each composite went through, replayed and recorded."""
    from .program import running_path

    for topic in states:
        name = topic.rsplit('/', 2)[-2]
        live = running_path([s.state for s in recording.states if s.topic == topic])
        again = replayed.paths.get(name, [])
        if live or again:
            print(f'Running sub-FSM of {name}, replayed: {" -> ".join(again) or "-"}')
            print(f'{"recorded: ":>{len(name) + 29}}{" -> ".join(live) or "-"}')


def _print_differences(plan: Plan, ticks: list[float], recording: Recording, replayed: Replayed) -> float:
    """The largest differences per joint and per Task; returns the largest of all."""
    from .compare import command_differences, task_difference
    from .program import TASK_ROWS, TASK_STATE

    worst: dict[str, float] = {}
    for program, topic in plan.commands.items():
        print(f'commands of {program} (rad/s):')
        for largest in command_differences(ticks, recording.per_tick(topic), replayed.outputs[topic]):
            print(largest.line('difference'))
            worst['command'] = max(worst.get('command', 0.0), largest.value)
    for kind, what, title in ((TASK_STATE, 'error', 'task errors:'),
                              (TASK_ROWS, 'rows', 'task rows (desired, lower, upper):')):
        print(title)
        for topic in plan.of_kind(kind):
            largest = task_difference(topic.rsplit('/', 3)[-3], ticks, recording.per_tick(topic),
                                      replayed.outputs[topic])
            print(largest.line(f'{what} difference'))
            worst[f'task {what}'] = max(worst.get(f'task {what}', 0.0), largest.value)
    for what, value in worst.items():
        print(f'largest {what} difference {value:.3e}')
    return max(worst.values(), default=0.0)


def _app_of(bag: Path, *, recorded: str | None) -> str:
    """The model file the bag was ``recorded`` from (its custom_data), else (a bag from elsewhere,
    or without it) the application its topics are named after."""
    from itasc_core.composition.loader import ModelError

    from ..apps import resolve_app
    from .recording import topic_names

    if recorded and Path(recorded).is_file():
        return recorded
    names = {t.split('/')[1] for t in topic_names(bag) if t.count('/') >= 2}
    if len(names) != 1:
        raise ReplayError(f'{bag}: cannot tell the application from its topics ({sorted(names)}); give --app')
    name = names.pop()
    if recorded:
        try:
            resolve_app(name)
        except ModelError:
            raise ReplayError(f'{bag} was recorded from {recorded}, which is not here, and no application is '
                              f'named {name!r}; give --app') from None
    return name


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog='itasc-replay', description=__doc__.split('\n\n')[0])
    parser.add_argument('bag', type=Path, help='a recording: bag folder or .mcap file')
    parser.add_argument('--app', default=None, help='application name or model path (default: the recorded one)')
    parser.add_argument('--tolerance', type=float, default=1e-9,
                        help="largest allowed difference of a command (rad/s), a Task's error or rows (default 1e-9)")
    args = parser.parse_args(argv)
    if not args.tolerance >= 0.0 or args.tolerance == float('inf'):  # NaN too
        parser.error(f'--tolerance must be a finite number >= 0, not {args.tolerance:g}')
    from itasc_core.composition.loader import ModelError
    try:
        if not args.bag.exists():
            raise ReplayError(f'{args.bag}: no such bag')
        from ..recording.bag import APPLICATION_KEY, DEPLOY_KEY
        from .recording import custom_data
        recorded = custom_data(args.bag)
        return replay(args.bag, args.app or _app_of(args.bag, recorded=recorded.get(APPLICATION_KEY)),
                      tolerance=args.tolerance, deploy=recorded.get(DEPLOY_KEY))
    except (ModelError, ReplayError) as err:
        print(f'error: {err}', file=sys.stderr)
        return 2

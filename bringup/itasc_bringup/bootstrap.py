# PYTHON_ARGCOMPLETE_OK
"""The bootstrap (paper §6.1): the root Composer's owner, run as ``ros2 run itasc_bringup bootstrap``.

It validates the application model (a wrong model exits 2 before anything starts), brings up the
root composite's Coordinator, Composer and Configurator (configuring the root Configurator with
the model's configurations), commands ``e_<root>_configure`` and lets the life-cycle bring the
hierarchy to Running. On ``--duration`` expiry, Ctrl-C, SIGTERM or an operator's ``~/stop`` of any
composite (``e_stop_requested`` reaching the root) it raises ``e_<root>_stop`` (once it heard of
every composite, see :data:`DISCOVERY_TIMEOUT`) and waits for the
orderly Stop of the whole hierarchy, and until every composite's final state was seen (and
recorded), then exits: 0 after an orderly stop from Running, 3 when the run ended in Safety (the
reason is printed on one line), 4 when it went through Safety and an operator recovered it
(``~/recover``) before the orderly stop from Running, 2 for a wrong model or a failure before
Running (what was started is stopped in order first), 1 when the hierarchy did not stop in time.

What it prints is :mod:`itasc_bringup.console`'s: a live view on a terminal, plain lines
otherwise (``-v`` for every transition), the full trace in the ROS log directory, and a summary
at the end (``--summary-json FILE`` for scripts).

    bootstrap <app name or model path> [--duration SECONDS] [--record DIR|FILE.mcap]
              [--deploy single|per-composite] [--rate HZ] [-v] [--summary-json FILE]
"""

from __future__ import annotations

import argparse
import contextlib
import faulthandler
import io
import math
import os
import pathlib
import re
import signal
import sys
import time

from .between_ticks import MODES, SPIN_FROM, SPIN_RATE, WAIT_BELOW, BetweenTicks

__all__ = ['main', 'parse_args']

#: How long an orderly Stop may take before the bootstrap gives up waiting.
STOP_TIMEOUT = 20.0
#: How long, after the root stopped, the final states of the other composites may take to arrive
#: (a composite process's state travels over DDS; a dead one's never comes).
FINAL_STATES_TIMEOUT = 3.0
#: How long a stop may wait, once the root was Running, until every composite was heard of: DDS
#: discovers a composite process at times only after the root is Running (0.3-1.2 s after the
#: process started, here; longer while this process stalls), and one that stopped and ended before
#: left the console and the recording without any of its states.
DISCOVERY_TIMEOUT = 3.0
#: How often the loop between ticks looks after the run (console, stop requests, the hierarchy's
#: state, retired nodes) [s]: at 1 kHz doing so after every spin cost a tenth of each period.
HOUSEKEEPING_PERIOD = 0.01


EXAMPLES = """\
examples:
  bootstrap approach_object --duration 20                     # the paper's running example, 20 s
  bootstrap approach_object --duration 10 --record out/run    # record a rosbag2 bag, then: itasc-plot out/run
  bootstrap pattern_demo --deploy per-composite -v            # a process per composite, every transition
"""


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    from .model.locations import known_apps
    apps = known_apps()
    parser = argparse.ArgumentParser(
        prog='bootstrap', description='Run an iTaSC application model.',
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=f'applications: {", ".join(apps)}\n\n{EXAMPLES}\n'
               'exit codes: 0 orderly stop from Running; 1 the hierarchy did not stop in time;\n'
               '  2 wrong model or DDS setting, or the application already running in this ROS domain\n'
               '  here (nothing was started), or a failure before Running (what was started is\n'
               '  stopped in order); 3 the run ended in Safety; 4 it went through Safety, was\n'
               '  recovered (~/recover) and stopped in order from Running; 5 it stopped in order\n'
               '  from Running but its --record recording is incomplete\n\n'
               'shell completion: eval "$(register-python-argcomplete bootstrap)"')
    app = parser.add_argument('app', help='application name (config/apps/<name>.yaml) or path to a model file')
    app.completer = _app_completer(apps)  # type: ignore[attr-defined]  # argcomplete reads it
    parser.add_argument('--duration', type=float, default=None,
                        help='stop SECONDS after the root reached Running (a failure before Running stops at once)')
    parser.add_argument('--record', metavar='DIR|FILE.mcap', default=None,
                        help='record the run: a rosbag2 bag folder DIR (metadata.yaml + MCAP), or one FILE.mcap')
    parser.add_argument('--deploy', choices=('single', 'per-composite'), default='single')
    parser.add_argument('--rate', type=float, default=None, help='override the Timer rate (Hz)')
    parser.add_argument('--between-ticks', choices=MODES, default='auto',
                        help='between two ticks, wait for the next one or spin (a core busy; on a virtual machine '
                             f'the ticks are up to a third faster); auto: spin at {SPIN_RATE:g} Hz and more once '
                             f'the ticks take {SPIN_FROM * 100:.0f}%% of the period waiting, until they would take '
                             f'less than {WAIT_BELOW * 100:.0f}%% (default)')
    parser.add_argument('--thread-priority', type=int, default=50, metavar='PRIORITY',
                        help='the real-time (SCHED_FIFO) priority, 1-99, of the threads that tick while the '
                             'application runs and they wait between ticks, where permitted; 0: normal scheduling '
                             '(default: 50, as ros2_control)')
    parser.add_argument('-v', '--verbose', action='store_true',
                        help='print every transition of every composite ([state] lines) and [status] lines')
    parser.add_argument('--summary-json', metavar='FILE', type=pathlib.Path, default=None,
                        help='also write the end-of-run summary as JSON to FILE')
    import argcomplete
    argcomplete.autocomplete(parser)
    args = parser.parse_args(argv)
    from itasc_core.composition.model import MAX_RATE, MIN_RATE
    if args.duration is not None and not 0 < args.duration < math.inf:
        parser.error(f'--duration must be a finite number of seconds > 0 (got {args.duration})')
    if args.rate is not None and not MIN_RATE <= args.rate <= MAX_RATE:
        parser.error(f'--rate must be between {MIN_RATE:g} and {MAX_RATE:g} Hz (got {args.rate})')
    if not 0 <= args.thread_priority <= 99:
        parser.error(f'--thread-priority must be 0 (normal scheduling) or 1-99 (got {args.thread_priority})')
    if args.summary_json is not None and not args.summary_json.parent.is_dir():
        parser.error(f'--summary-json: no directory {args.summary_json.parent}')
    from itasc_core.composition.hosts import HOST_NAME
    if (host := os.environ.get('ITASC_HOST')) and not re.match(HOST_NAME, host):  # as the host agent checks it
        parser.error(f'ITASC_HOST must be a host name like arm_pc (letters, digits, _), got {host!r}')
    return args


def _app_completer(apps: list[str]):
    """Completes the application names, and model files as paths."""
    from argcomplete.completers import FilesCompleter

    files = FilesCompleter(allowednames=('yaml', 'yml'))
    return lambda prefix, **kwargs: [a for a in apps if a.startswith(prefix)] + list(files(prefix, **kwargs))


def load(app: str, rate: float | None):
    """The validated composition model, or exit 2 with the model error."""
    from itasc_core.composition.loader import ModelError
    from itasc_bringup.apps import load_composition
    try:
        model = load_composition(app)
    except ModelError as err:
        print(f'error: {err}', file=sys.stderr)
        raise SystemExit(2) from None
    if rate is not None:
        model = model.model_copy(update={'rate': rate})
    return model


def main(argv: list[str] | None = None) -> int:
    with contextlib.suppress(io.UnsupportedOperation):  # stderr without a file (main() called in a test)
        faulthandler.register(signal.SIGUSR1, all_threads=True)  # `kill -USR1 <pid>`: where is it stuck?
    # From the start: a Ctrl-C during the imports and the model's validation (the first second) is
    # a stop like any other, not a KeyboardInterrupt traceback
    stop_requested: list[str] = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda signum, _frame: stop_requested.append('signal ' + signal.Signals(signum).name))
    args = parse_args(argv)
    model = load(args.app, args.rate)

    from itasc_core.communication.dds import DdsSettingsError, configure_dds
    try:
        configure_dds()
    except DdsSettingsError as err:  # a wrong ROS_DOMAIN_ID or ITASC_DDS_PEERS/INTERFACES: nothing started
        print(f'error: {err}', file=sys.stderr)
        return 2
    from .instance import AlreadyRunning, InstanceLock
    instance = InstanceLock(model.name)
    try:  # before this process joins DDS: its events would reach the running instance
        instance.acquire()
    except AlreadyRunning as err:
        print(f'error: {err}', file=sys.stderr)
        return 2
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    from itasc_core.communication.event_names import CONFIGURE, STOP, event
    from itasc_core.communication.events import EventRaiser
    from itasc_core.composition.composer import bring_up
    from itasc_core.composition.deployment import RecordTo, Runtime, make_executor, end_process_within
    from itasc_core.composition.model import walk
    from itasc_core.composition.realtime import ENV as PRIORITY_ENV
    from itasc_core.composition.realtime import ThreadPriority
    from itasc_core.composition.zygote import zygote_for
    from itasc_core.entity import CompositeContext

    from .console import RunFacts, TraceFile, Watch, task_specs
    from .outcome import EXIT_ERROR, EXIT_OK, EXIT_RECORDING, RunOutcome

    if stop_requested:  # nothing started yet
        print(f'{model.name}: stopped ({stop_requested[0]}) before the bring-up began - exit 0')
        return 0

    started = time.monotonic()
    age = process_age()  # the interpreter's start, the imports and the model's validation
    os.environ[PRIORITY_ENV] = str(args.thread_priority)  # the composite processes tick at it too
    zygote = zygote_for(model) if args.deploy == 'per-composite' else None  # before DDS starts threads
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    executor = make_executor()
    root = CompositeContext(name=model.name, namespace=f'/{model.name}')
    runtime = Runtime(executor=executor, mode=args.deploy, namespace=root.namespace, background=True, zygote=zygote)
    node = rclpy.create_node('bootstrap', namespace=root.namespace)
    executor.add_node(node)
    # the data flow that the console and the recorder tap once its outputs exist here: that of the
    # composites this process runs; any other topic they read over DDS from the start (see .observe)
    from .recording.topics import data_flow_topics
    remote = tuple(f'{path}/' for path, composite in walk(model)
                   if composite is not model and runtime.separate(composite))
    data_flow = data_flow_topics(model, namespace=root.namespace)
    tapped_here = {topic for topic in data_flow if not topic.startswith(remote)}
    # a recorded run's composite processes on this machine record their own outputs (sample_stream)
    other_hosts = tuple(f'{path}/' for path, composite in walk(model)
                        if composite is not model and runtime.elsewhere(composite))
    streamed = {topic for topic in data_flow if topic.startswith(remote) and not topic.startswith(other_hosts)}

    def elsewhere(topic: str) -> bool:
        return topic not in tapped_here
    recorder = None
    composer = None
    console = None
    trace = TraceFile(app=model.name)
    try:
        if args.record:
            from itasc_core.communication.qos import EVENT_QOS, STATE_QOS

            from .apps import resolve_app
            from .recording.bag import APPLICATION_KEY, DEPLOY_KEY, CannotRecord, mcap_path_of
            from .recording.recorder import Recorder
            try:  # the model file goes into the bag: itasc-replay finds it there
                recorder = Recorder(path=args.record, prefix=root.namespace,
                                    elsewhere=lambda topic: elsewhere(topic) and topic not in streamed,
                                    custom_data={APPLICATION_KEY: str(resolve_app(args.app).resolve()),
                                                 DEPLOY_KEY: args.deploy})
            except CannotRecord as err:
                print(f'error: --record: {err}', file=sys.stderr)
                return 2
            runtime.record_to = RecordTo(recorder.stream_address, root.namespace)
            for path, _ in walk(model):  # every event of the bring-up, not only those after discovery
                recorder.record(f'{path}/events', 'itasc_msgs/msg/Event', qos=EVENT_QOS)
                recorder.record(f'{path}/state', 'itasc_msgs/msg/CoordinatorState', qos=STATE_QOS)
            recorder.record_model(model, namespace=root.namespace)  # the data flow from the first tick
            executor.add_node(recorder)
        composites = {m.name: path for path, m in walk(model)}
        outcome = RunOutcome(node, composites=composites)
        facts = RunFacts(composites=composites, tasks=task_specs(model, namespace=root.namespace))
        running_since: float | None = None
        ran_for: float | None = None  # Running, until the stop was commanded
        console = _make_console(args, facts=facts, outcome=outcome, root=root.name, trace=trace,
                                target_rate=model.rate or 0.0,
                                rate=lambda: (composer.timer.achieved_rate() if composer and composer.timer else 0.0)
                                or facts.achieved_rate(),
                                elapsed=lambda: None if running_since is None
                                else ran_for or time.monotonic() - running_since)

        from .console import Waits
        waits = Waits(model)

        def running() -> None:
            """The root is Running: the run's time and ticks count, the display joins."""
            nonlocal running_since
            if running_since is None:
                running_since = time.monotonic()
                watch.count(composer.timer if composer is not None else None, since=running_since)
                visualization.join()

        def on_transition(transition) -> None:
            # when the root was seen Running, in the order the transitions came: a Safety seen after
            # it is a fault while running, not a failed start, however late the housekeeping looks
            if transition.composite == root.name and transition.state.startswith('Active.Run.Running'):
                running()
            outcome.saw_state(transition.composite, transition.state)
            console.on_transition(transition)
            waits.on_transition(transition)

        solver_topics = [t for t, kind in data_flow.items() if kind == 'itasc_msgs/msg/SolverStatus']
        watch = Watch(node, facts=facts, solver_topics=solver_topics, on_transition=on_transition,
                      elsewhere=elsewhere)

        raiser = EventRaiser(node, topic=root.events_topic)
        composer = bring_up(model=model, context=root, runtime=runtime)
        coordinator = composer.coordinator
        # robot_description, TF, markers, /diagnostics
        from .visualization import FIRST_DRAWING_TIMEOUT, start_visualization
        visualization = start_visualization(args.app, model=model, node=node, composer=composer, recorder=recorder,
                                            observers=[watch.observer], states=watch.on_state)

        raiser.raise_event(event(root.name, CONFIGURE))  # the root's Coordinator, in this process: by its event hub

        stop_sent_at = last_stop = stop_due_at = None
        undrawn: list[str] = []
        code = None
        failed_start = False
        housekeeping_at = 0.0
        recording_lost: str | None = None

        def between_changed(spinning: bool, share: float) -> None:
            if share:  # not when the hierarchy stopped computing
                console.show(f'{"spinning" if spinning else "waiting"} between ticks: they take {share:.0%} of '
                             'the period (--between-ticks)')
        priority = ThreadPriority(args.thread_priority, refused=lambda why: console.show(f'{why} (--thread-priority)'))
        between = BetweenTicks(args.between_ticks, timer=lambda: composer.timer, on_change=between_changed,
                               alone=lambda: not runtime.local_processes, priority=priority)
        while True:
            between.step(executor)
            if recorder is not None:
                recorder.drain()  # the samples of the tick that just ran: CDR bytes, to the writer
            if time.monotonic() < housekeeping_at:
                continue
            housekeeping_at = time.monotonic() + HOUSEKEEPING_PERIOD
            if outcome.stop_request is not None and not stop_requested:  # an operator's ~/stop
                stop_requested.append(f'~/stop: {outcome.stop_request}')
            runtime.reap()
            if recorder is not None and recording_lost is None and (recording_lost := recorder.failure):
                console.show(f'warning: --record: {recording_lost}: nothing more is recorded')
            watch.poll(composer.timer)
            console.show_safety()
            for fault in outcome.lasting_faults() if stop_sent_at is None else ():  # the summary says the later ones
                console.show(f'warning: {fault}')
            for line in waits.due():
                console.show(line)
            console.refresh()
            state = coordinator.state
            if state.startswith('Active.Run.Running'):
                running()
            due = args.duration is not None and running_since is not None \
                and time.monotonic() - running_since >= args.duration
            # a failure on the way to Running (a composite was in Safety before the root was seen
            # running: e.g. a fault at the first tick, whose Safety overtakes the children's
            # Running notifications): stop what was started, in order
            failed_start = failed_start or outcome.went_through_safety and (
                running_since is None or min(outcome.in_safety.values()) <= running_since)
            if stop_sent_at is None and (stop_requested or due or failed_start):
                stop_due_at = stop_due_at or time.monotonic()
                if failed_start or running_since is None or not facts.unseen() \
                        or time.monotonic() - stop_due_at > DISCOVERY_TIMEOUT:
                    raiser.raise_event(event(root.name, STOP))
                    stop_sent_at = last_stop = time.monotonic()
                    watch.count(composer.timer, until=stop_sent_at)
                    since = running_since  # a local: the console's lambdas read running_since too
                    ran_for = time.monotonic() - since if since is not None else None
            elif stop_sent_at is not None and state == 'Safety' and time.monotonic() - (last_stop or 0.0) > 0.5:
                # a fault during the Stop put the root in Safety: the stop still stands (Safety ->
                # Stop), or the hierarchy would wait in Safety for a command already given
                raiser.raise_event(event(root.name, STOP))
                last_stop = time.monotonic()
            if state.endswith('NotifyStopped'):
                _await_final_states(executor, facts=facts, outcome=outcome, recorder=recorder,
                                    composites=composites)
                visualization.join()  # a run that ended before Running is shown too
                # before the first tick there is no joint state to draw the scene from
                ticked = composer.timer is not None and composer.timer.ticked > 0
                if recorder is not None and ticked and (missing := _await_first_drawing(executor, visualization,
                                                                                        recorder)):
                    undrawn.append(f'the recording holds no {", ".join(missing)}: the visualization process did not '
                                   f'draw the 3-D scene within {FIRST_DRAWING_TIMEOUT:g} s of joining')
                break
            if stop_sent_at is not None and time.monotonic() - stop_sent_at > STOP_TIMEOUT:
                print(f'error: the hierarchy did not stop within {STOP_TIMEOUT} s (state {state})', file=sys.stderr)
                code = EXIT_ERROR
                break
        priority.realtime(False)  # the teardown is no tick
        watch.poll(composer.timer)  # the last ticks' samples, for the summary
        console.show_safety()
        if recorder is not None:  # finished before the verdict, which says whether it is whole
            # after the composite processes ended: what they streamed to the recording is all there
            runtime.shutdown(orderly=coordinator.state.endswith('NotifyStopped'))
            recorder.close()
            recording_lost = recorder.failure
        lost = [] if recording_lost is None else [
            f'the recording {args.record} is incomplete: {recording_lost}; what it wrote until then can be read '
            f'after itasc-recover {mcap_path_of(pathlib.Path(args.record))}']
        warnings = list(outcome.warnings()) + undrawn + lost + [
            f'no state of composite {name} was received ({composites[name]}/state): DDS did not discover its process '
            'in time, the console and the recording miss it' for name in facts.unseen() if name in outcome.configured]
        for warning in warnings:
            trace.write(f'warning: {warning}')
            print(f'warning: {warning}', file=sys.stderr)
        how = 'failed to start' if failed_start else stop_requested[0] if stop_requested else 'duration'
        if code == EXIT_ERROR:
            how = 'did not stop in time'
        elif outcome.went_through_safety:
            how += ', went through Safety' + (', recovered' if outcome.recovered else '')
        code = outcome.exit_code(reached_running=not failed_start) if code is None else code
        if lost and code == EXIT_OK:
            code, how = EXIT_RECORDING, how + ', recording incomplete'
        _finish(console, args, facts=facts, app=root.name, how=how, exit_code=code, trace=trace,
                safety=outcome.safety_line() if outcome.went_through_safety else None,
                running_for=ran_for, up_after=None if running_since is None else running_since - started,
                process_up_after=None if running_since is None or age is None else running_since - started + age,
                target_rate=model.rate or 0.0, recording=args.record if recorder is not None else None,
                warnings=warnings)
        return code
    finally:
        # how the run ended is decided (and said): further signals change nothing; ignored, not
        # handled, so that none lands on the default handler the interpreter's finalization puts back
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, signal.SIG_IGN)
        if console is not None:
            console.close()
        stopped = composer is not None and composer.coordinator.state.endswith('NotifyStopped')
        runtime.shutdown(orderly=stopped)  # the composite processes, each under its own deadline
        if recorder is not None:
            recorder.close()
        end_process_within()
        runtime.reap(wait=True)
        if composer is not None:
            for entity in (composer.coordinator, composer.configurator, composer):
                executor.remove_node(entity)
                entity.destroy_node()
        node.destroy_node()
        rclpy.try_shutdown()
        trace.close()
        instance.release()


def _await_final_states(executor, *, facts, outcome, recorder, composites: dict[str, str]) -> None:
    """Spin until the final state of every composite was seen by the console and written by the
    recorder, except those a Composer stopped on behalf of a dead process and those never told to
    configure (a stop during the bring-up); at most :data:`FINAL_STATES_TIMEOUT` s."""
    def final(name: str) -> bool:
        if name in outcome.stopped_on_behalf or name not in outcome.configured:
            return True
        if not facts.states[name].endswith('NotifyStopped'):
            return False
        if recorder is None:
            return True
        written = recorder.last(f'{composites[name]}/state')
        return written is not None and written.state.endswith('NotifyStopped')

    deadline = time.monotonic() + FINAL_STATES_TIMEOUT
    while not all(map(final, composites)) and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.01)


def _await_first_drawing(executor, visualization, recorder) -> list[str]:
    """A short run may end before the visualization process drew the scene once (its imports take
    seconds on a loaded machine): spin until the recording holds it, at most until
    :data:`~.visualization.FIRST_DRAWING_TIMEOUT` after the process joined (the feed keeps the
    last samples, so it draws the final state). The scene's topics the recording still holds
    nothing of (any of them missing leaves ``itasc-plot`` without a 3-D scene)."""
    while not visualization.drawn(recorder):
        executor.spin_once(timeout_sec=0.01)
        recorder.drain()
    return visualization.missing(recorder)


def _make_console(args: argparse.Namespace, **kwargs):
    """The live view on a terminal, plain lines otherwise."""
    from .console import LiveConsole, PlainConsole
    if sys.stdout.isatty():
        return LiveConsole(duration=args.duration, verbose=args.verbose, **kwargs)
    kwargs.pop('target_rate'), kwargs.pop('elapsed')
    return PlainConsole(verbose=args.verbose, **kwargs)


def process_age() -> float | None:
    """Seconds since this process started (Linux: its start time in ``/proc/self/stat``, in clock
    ticks since boot, against ``CLOCK_BOOTTIME``); None where that cannot be read."""
    try:
        stat = pathlib.Path('/proc/self/stat').read_text()
        ticks = int(stat.rsplit(')', 1)[1].split()[19])  # field 22, starttime; the name may hold spaces
        return time.clock_gettime(time.CLOCK_BOOTTIME) - ticks / os.sysconf('SC_CLK_TCK')
    except (OSError, ValueError, IndexError, AttributeError):
        return None


def _finish(console, args: argparse.Namespace, *, facts, trace, **summary) -> None:
    """The summary: on the console, into the trace, and with ``--summary-json`` into its file."""
    from .console import build_summary, summary_lines, write_summary_json
    data = build_summary(facts, trace=str(trace.path) if trace.path else None, **summary)
    console.finish(summary_lines(data))
    if args.summary_json is not None:
        try:
            write_summary_json(data, args.summary_json)
        except OSError as err:
            print(f'error: --summary-json: {err}', file=sys.stderr)

if __name__ == '__main__':
    sys.exit(main())

"""The real application, side by side with what it costs at least (issue #9).

One measurement (``--json``): the application runs through the bootstrap, as a user runs it
(``python -m itasc_bringup.bootstrap APP --rate HZ --duration S``, console, visualization and
``--record`` included), in a ROS domain of its own; its summary gives the achieved rate, the tick
times and when the root reached Running, its console whether its thread spun between ticks when
the run ended (``spinning_at_end``, ``itasc_bringup.between_ticks``). In the same run, on the same
problem (the Tasks active in the initial state of its Running sub-FSM):

* ``solver_p50_us``: the solver step alone (:class:`fused.FusedProgram`: Scene update, every
  Task's rows and the QP, no entities, ports or messages), timed back to back in a process of its
  own; ``solver_paced_p50_us``: the same step paced at the requested rate, one step a period as
  the Timer ticks (``tick_over_solver`` and ``tick_over_solver_paced`` divide the tick by each),
  and its p99 ``solver_paced_p99_us``: what the machine's own jitter makes of the plain computation;
* ``handwritten_p50_us`` (and ``_p99_us``): the cycle of a hand-written rclpy node doing the same
  with its driver in another process (:mod:`handwritten`).

A composition model (``composite:``, no constraint-based program) has no solver step and no
hand-written equivalent: those figures are null and ``baseline`` says why. A Driver that talks to
an outside driver (``ros2_control``) is run against the stand-in its kind names
(:mod:`stand_ins`, ``fake_ros2_control``), unless ``--drivers external`` says that the real one runs.

    python bench/bench_app.py --app NAME --rate HZ --seconds S [--deploy single|per-composite] [--record]
                              [--drivers stand-in|external] --json

Without ``--json`` (``make bench``): the whole comparison (rates 100/500/1000 Hz, ``--record``,
``--deploy per-composite``, 1..50 Tasks, 7 and 38 DOF, the reaction to a Monitor), written to
``bench/RESULTS.md`` and ``bench/results.png`` with the machine, versions, date and load.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import pathlib
import platform
import subprocess
import sys
import tempfile
import threading
import time

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

#: The tick rate of the scaling runs (Tasks, DOF) [Hz].
SCALING_RATE = 100.0


def _domain() -> int:
    """A ROS domain for this benchmark's processes, so that they see no other run on the machine."""
    if 'ITASC_BENCH_DOMAIN' in os.environ:
        return int(os.environ['ITASC_BENCH_DOMAIN'])
    return 102 + os.getpid() % 100  # the tests use 1..101


def _env() -> dict[str, str]:
    return dict(os.environ, ROS_DOMAIN_ID=str(_domain()))


def _load() -> float:
    return os.getloadavg()[0]


def _root_name(app: str) -> str:
    from itasc_bringup.apps import load_composition
    return load_composition(app).name


def model_error(app: str) -> str | None:
    """What is wrong with the model ``app`` names, as the bootstrap says it (one line), or None: a
    benchmark refuses a wrong model before it starts anything, as the bootstrap does."""
    from itasc_core.composition.loader import ModelError
    try:
        _root_name(app)
    except ModelError as err:
        return f'error: {err}'
    return None


def application(app: str):
    """The checked application model of ``app`` (``load_application``), or None for a composition
    model (``composite:``), which has no constraint-based program."""
    from itasc_bringup.apps import resolve_app
    from itasc_bringup.model import load_application
    from itasc_core.composition.loader import ModelError
    try:
        return load_application(resolve_app(app))
    except ModelError:  # the bootstrap says what is wrong with a model that is neither
        return None


def run_app(app: str, *, rate: float, seconds: float, deploy: str = 'single', record: bool = False,
            between_ticks: str = 'auto', stand_ins_of=None) -> dict:
    """The application through the bootstrap (against the stand-ins of the outside drivers of
    ``stand_ins_of``, its checked model): its summary's figures, and when the console said that
    the root is Running (seconds after the process started)."""
    from stand_ins import StandIns
    running_line = f'[state] {_root_name(app)}: Active.Run.Running'
    drivers = StandIns(stand_ins_of, rate=rate, env=_env())
    with tempfile.TemporaryDirectory(prefix='bench_app_') as tmp, drivers:
        summary_path = pathlib.Path(tmp) / 'summary.json'
        command = [sys.executable, '-m', 'itasc_bringup.bootstrap', app, '--rate', str(rate),
                   '--duration', str(seconds), '--deploy', deploy, '--between-ticks', between_ticks,
                   '--summary-json', str(summary_path)]
        if record:
            command += ['--record', str(pathlib.Path(tmp) / 'run')]
        load = _load()
        began = time.monotonic()
        process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env())
        running_at: list[float] = []
        out: list[str] = []

        def read() -> None:
            for line in process.stdout:
                if not running_at and line.startswith(running_line):
                    running_at.append(time.monotonic() - began)
                out.append(line)
        reader = threading.Thread(target=read, daemon=True)
        reader.start()
        try:
            err = process.stderr.read()  # until the bootstrap ends
            process.wait(timeout=30)
        finally:
            if process.poll() is None:
                process.kill()
        reader.join(timeout=5)
        died = '\n'.join(drivers.died())
        if not summary_path.exists():
            raise RuntimeError(f'{app} failed (exit {process.returncode}):\n{"".join(out)[-3000:]}\n'
                               f'{err[-3000:]}\n{died}')
        summary = json.loads(summary_path.read_text())
        recorded = _recorded_messages(pathlib.Path(tmp) / 'run') if record else None
    rate_ = summary['rate']
    if rate_['tick_p50'] is None:
        raise RuntimeError(f"{app}: no tick ({summary['ended']}, exit {summary['exit_code']}):\n{err[-3000:]}\n{died}")
    return {
        'achieved_hz': rate_['achieved'], 'tick_p50_us': rate_['tick_p50'] * 1e6,
        'tick_p99_us': rate_['tick_p99'] * 1e6, 'ticks': rate_['ticks'], 'dropped_ticks': rate_.get('dropped', 0),
        # the Solver's steps a second from Running to the stop: with --deploy per-composite, its own process's rate
        'solver_hz': rate_['solver_hz'],
        'qp_p50_us': None if rate_.get('solve_p50') is None else rate_['solve_p50'] * 1e6,
        'bring_up_s': summary.get('up_after'), 'start_to_running_s': running_at[0] if running_at else None,
        'exit_code': summary['exit_code'], 'wall_s': time.monotonic() - began, 'load_before': load,
        'load_after': _load(), **({'recorded_messages': recorded} if recorded is not None else {}),
        'spinning_at_end': _spinning_at_end(between_ticks, out),
    }


def _spinning_at_end(mode: str, console: list[str]) -> bool:
    """Whether the bootstrap's thread spun between ticks when the run ended (``auto``: what the
    console said last, ``spinning between ticks: ...`` or ``waiting between ticks: ...``)."""
    if mode != 'auto':
        return mode == 'spin'
    said = [line for line in console if ' between ticks: they take ' in line]
    return bool(said) and said[-1].lstrip().startswith('spinning')


def _recorded_messages(bag: pathlib.Path) -> int:
    """How many messages the recording holds (its metadata)."""
    import yaml
    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())
    return int(meta['rosbag2_bagfile_information']['message_count'])


def run_handwritten(app: str, *, rate: float, seconds: float) -> dict:
    command = [sys.executable, str(HERE / 'handwritten.py'), app, '--rate', str(rate), '--seconds', str(seconds)]
    out = subprocess.run(command, capture_output=True, text=True, env=_env(), timeout=seconds + 120)
    line = next((line for line in out.stdout.splitlines() if line.startswith('RESULT ')), None)
    if line is None:
        raise RuntimeError(f'the hand-written node failed (exit {out.returncode}):\n{out.stderr[-3000:]}')
    return json.loads(line.removeprefix('RESULT '))


def run_fused(app: str, *, rate: float, steps: int = 3000, paced_seconds: float = 3.0) -> dict:
    """The solver step alone, in a process of its own (this one stays free of pinocchio state):
    back to back, and paced at ``rate`` for ``paced_seconds`` as the application's Timer paces
    its ticks (on these VMs a step that follows a pause of a period takes up to twice as long as
    one that follows another step)."""
    code = ('import json, sys, statistics; sys.path.insert(0, %r)\n'
            'from fused import FusedProgram\n'
            'from itasc_bringup.apps import resolve_app\n'
            'from itasc_bringup.model import load_application\n'
            'p = FusedProgram.of(load_application(resolve_app(%r)))\n'
            'full, solve = p.time_steps(steps=%d, dt=%r)\n'
            'paced, _ = p.time_steps(steps=%d, dt=%r, paced=True)\n'
            'print("RESULT " + json.dumps({"solver_p50_us": statistics.median(full) * 1e6,'
            ' "qp_alone_p50_us": statistics.median(solve) * 1e6,'
            ' "solver_paced_p50_us": statistics.median(paced[len(paced) // 10:]) * 1e6,'
            ' "solver_paced_p99_us": statistics.quantiles(paced[len(paced) // 10:], n=100)[98] * 1e6}))\n'
            ) % (str(HERE), app, steps, 1.0 / rate, max(100, int(paced_seconds * rate)), 1.0 / rate)
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, timeout=600)
    line = next((line for line in out.stdout.splitlines() if line.startswith('RESULT ')), None)
    if line is None:
        raise RuntimeError(f'the solver step failed:\n{out.stderr[-3000:]}')
    return json.loads(line.removeprefix('RESULT '))


#: The figures of the solver step alone and of the hand-written node (null without a baseline).
BASELINE_KEYS = ('solver_p50_us', 'qp_alone_p50_us', 'solver_paced_p50_us', 'solver_paced_p99_us', 'handwritten_p50_us',
                 'handwritten_p99_us', 'handwritten_hz', 'tick_over_solver', 'tick_over_solver_paced',
                 'tick_over_handwritten')


def measure(app: str, *, rate: float, seconds: float, deploy: str = 'single', record: bool = False,
            between_ticks: str = 'auto', baseline: bool = True, stand_ins: bool = True) -> dict:
    """One application run and, in the same run, its solver step alone and the hand-written node
    (none for a composition model: ``baseline`` says so)."""
    result = {'app': app, 'rate_hz': rate, 'deploy': deploy, 'record': record, 'between_ticks': between_ticks,
              'seconds': seconds}
    model = application(app)
    if baseline and model is None:
        baseline = False
        result |= dict.fromkeys(BASELINE_KEYS) | {
            'baseline': f'none: {app} is a composition model (composite:), it has no constraint-based program'}
    before = run_fused(app, rate=rate) if baseline else None
    result |= run_app(app, rate=rate, seconds=seconds, deploy=deploy, record=record, between_ticks=between_ticks,
                      stand_ins_of=model if stand_ins else None)
    if model is not None and not result['solver_hz']:  # tick times of a program that never computed
        raise RuntimeError(f'{app}: the Solver never solved in {seconds:g} s (no joint states from a driver?)')
    if before is not None:  # the solver step alone, before and after the run: the load drifts
        after = run_fused(app, rate=rate)
        result |= {key: (before[key] + after[key]) / 2 for key in before}
        hand = run_handwritten(app, rate=rate, seconds=min(seconds, 10.0))
        result |= {'handwritten_p50_us': hand['cycle_p50_us'], 'handwritten_p99_us': hand['cycle_p99_us'],
                   'handwritten_hz': hand['achieved_hz']}
        result['tick_over_solver'] = result['tick_p50_us'] / result['solver_p50_us']
        result['tick_over_solver_paced'] = result['tick_p50_us'] / result['solver_paced_p50_us']
        result['tick_over_handwritten'] = result['tick_p50_us'] / result['handwritten_p50_us']
    result['load_end'] = _load()
    return result


# -- make bench: the whole comparison ---------------------------------------------------------------

def machine() -> dict:
    from importlib.metadata import PackageNotFoundError, version

    import numpy
    import pinocchio
    cpu = next((line.split(':', 1)[1].strip() for line in open('/proc/cpuinfo') if line.startswith('model name')),
               platform.processor())
    versions = {'python': platform.python_version(), 'numpy': numpy.__version__, 'pinocchio': pinocchio.__version__}
    for package in ('qpsolvers', 'daqp', 'rclpy'):
        try:
            versions[package] = version(package)
        except PackageNotFoundError:
            pass
    return {'cpu': cpu, 'cores': os.cpu_count(), 'versions': versions,
            'date': datetime.datetime.now().isoformat(timespec='seconds')}


def scaling_app(directory: pathlib.Path, *, tasks: int, robot: str = 'panda') -> pathlib.Path:
    """A generated application: ``tasks`` Tasks on one robot (``panda``, 7 DOF, or ``talos``, 38
    DOF on a free-flyer), every Task active, no Running sub-FSM."""
    import yaml
    from scaling import application
    path = directory / f'scale_{robot}_{tasks}.yaml'
    path.write_text(yaml.safe_dump(application(tasks=tasks, robot=robot), sort_keys=False))
    return path


def run_reaction(app: str, *, rate: float) -> dict:
    out = subprocess.run([sys.executable, str(HERE / 'reaction.py'), app, '--rate', str(rate)],
                         capture_output=True, text=True, env=_env(), timeout=300)
    line = next((line for line in out.stdout.splitlines() if line.startswith('RESULT ')), None)
    if line is None:
        raise RuntimeError(f'the reaction run failed (exit {out.returncode}):\n{out.stderr[-3000:]}')
    return json.loads(line.removeprefix('RESULT '))


def _attempt(what: str, run, *args, **kwargs) -> dict | None:
    """One measurement of the report; a failed one is said and left out."""
    try:
        return run(*args, **kwargs)
    except (RuntimeError, subprocess.TimeoutExpired) as err:
        print(f'{what}: FAILED ({str(err)[:2000]})', flush=True)
        return None


def report(args: argparse.Namespace) -> None:
    info = machine()
    print(f"machine: {info['cpu']}, {info['cores']} cores; {info['versions']}; load {_load():.2f}", flush=True)
    results: dict = {'machine': info, 'rates': [], 'record': None, 'per_composite': None,
                     'per_composite_record': None, 'tasks': [], 'dof': [], 'reaction': None}

    def run(what: str, into: list | None = None, extra: dict | None = None, **kwargs) -> dict | None:
        r = _attempt(what, measure, **kwargs)
        if r is not None:
            r |= extra or {}
            print(_line(what, r), flush=True)
            if into is not None:
                into.append(r)
        return r

    for rate in (100.0, 500.0, 1000.0):
        run(f'single {rate:g} Hz', results['rates'], app=args.app, rate=rate, seconds=args.seconds)
    results['record'] = run('single 1000 Hz --record', app=args.app, rate=1000.0, seconds=args.seconds, record=True)
    results['per_composite'] = run('per-composite 500 Hz', app=args.app, rate=500.0, seconds=args.seconds,
                                   deploy='per-composite', baseline=False)
    results['per_composite_record'] = run('per-composite 500 Hz --record', app=args.app, rate=500.0,
                                          seconds=args.seconds, deploy='per-composite', record=True, baseline=False)
    with tempfile.TemporaryDirectory(prefix='bench_scale_') as tmp:
        for n in (1, 5, 10, 20, 50):
            run(f'{n} tasks', results['tasks'], {'tasks': n}, app=str(scaling_app(pathlib.Path(tmp), tasks=n)),
                rate=SCALING_RATE, seconds=args.scaling_seconds, baseline=False)
        for robot in ('panda', 'talos'):
            try:
                path = scaling_app(pathlib.Path(tmp), tasks=5, robot=robot)
            except ImportError as err:
                print(f'{robot}: skipped ({err})')
                continue
            run(f'{robot}, 5 tasks', results['dof'], {'robot': robot}, app=str(path), rate=SCALING_RATE,
                seconds=args.scaling_seconds, baseline=False)
    results['reaction'] = _attempt('reaction', run_reaction, args.app, rate=1000.0)
    print(f"reaction: {results['reaction']}", flush=True)
    from results import write_results
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / 'results.json').write_text(json.dumps(results, indent=1))
    write_results(results, markdown=args.out / 'RESULTS.md', picture=args.out / 'results.png')
    print(f'wrote {args.out / "RESULTS.md"}, {args.out / "results.png"} and {args.out / "results.json"}')


def _line(what: str, r: dict) -> str:
    extra = ''
    if 'solver_p50_us' in r:
        extra = (f", solver step {r['solver_p50_us']:.0f} us (x{r['tick_over_solver']:.2f}), "
                 f"paced {r['solver_paced_p50_us']:.0f} us (x{r['tick_over_solver_paced']:.2f}, "
                 f"p99 {r['solver_paced_p99_us']:.0f} us), hand-written {r['handwritten_p50_us']:.0f} us "
                 f"(x{r['tick_over_handwritten']:.2f}, p99 {r['handwritten_p99_us']:.0f} us)")
    return (f"{what:28s} {r['achieved_hz']:7.1f} Hz, tick p50 {r['tick_p50_us']:6.0f} us, "
            f"p99 {r['tick_p99_us']:6.0f} us, "
            f"up after {r['bring_up_s'] or float('nan'):.2f} s (process start: "
            f"{r['start_to_running_s'] or float('nan'):.2f} s){extra}, load {r['load_before']:.1f}")


def main() -> int:
    from itasc_bringup.between_ticks import MODES
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--app', default='approach_object')
    parser.add_argument('--rate', type=float, default=1000.0)
    parser.add_argument('--seconds', type=float, default=30.0)
    parser.add_argument('--scaling-seconds', type=float, default=5.0, help='run time of the 1..50 Tasks runs')
    parser.add_argument('--deploy', choices=('single', 'per-composite'), default='single')
    parser.add_argument('--record', action='store_true')
    parser.add_argument('--between-ticks', choices=MODES, default='auto',
                        help="the bootstrap's --between-ticks (auto: spin while the ticks fill half the period)")
    parser.add_argument('--drivers', choices=('stand-in', 'external'), default='stand-in',
                        help="an outside driver (ros2_control): run the stand-in its kind names, or "
                             "'external': the real one runs already")
    parser.add_argument('--json', action='store_true', help='one measurement, printed as one JSON object')
    parser.add_argument('--out', type=pathlib.Path, default=HERE, help='where the report goes (default: bench/)')
    args = parser.parse_args()
    error = model_error(args.app)
    if error is not None:
        print(error, file=sys.stderr)
        return 2
    if not args.json:
        report(args)
        return 0
    result = measure(args.app, rate=args.rate, seconds=args.seconds, deploy=args.deploy, record=args.record,
                     between_ticks=args.between_ticks, stand_ins=args.drivers == 'stand-in')
    print(json.dumps(result))
    return 0


if __name__ == '__main__':
    sys.exit(main())

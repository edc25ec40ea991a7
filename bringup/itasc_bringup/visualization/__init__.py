"""Seeing a run (issue #13): ``robot_description``, TF, markers and ``/diagnostics``.

A tool concern, not part of the application: like the recorder and the status line it observes
the composites through their topics, so it lives in itasc_bringup next to them, never in the
Composition Pattern's packages (paper §3.1: an entity knows its own composite only). The
bootstrap calls :func:`start_visualization` once the root composite is up: diagnostics on its own
node (they read the Timer), robot_description, TF and markers in a process of their own
(:mod:`.node`), off the control path. Neither subscribes to a topic the tick publishes: they take
the newest samples of the output ports in this process when they draw (:mod:`.feed`), so the
control loop pays nothing per tick for them.
"""

from __future__ import annotations

import atexit
import ctypes
import signal
import subprocess
import sys
from collections.abc import Callable

import yaml

__all__ = ['start_visualization', 'GLOBAL_TOPICS']

#: Topics outside the application's namespace a recording must hold (type, QoS name).
GLOBAL_TOPICS = {'/tf': 'tf2_msgs/msg/TFMessage', '/tf_static': 'tf2_msgs/msg/TFMessage',
                 '/diagnostics': 'diagnostic_msgs/msg/DiagnosticArray'}


def _end_with_parent() -> None:
    """In the child, before exec: SIGTERM when the bootstrap dies, however it dies (Linux)."""
    ctypes.CDLL('libc.so.6', use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG


def _is_application(path) -> bool:
    with open(path, encoding='utf-8') as stream:
        data = yaml.safe_load(stream)
    return isinstance(data, dict) and 'application' in data


def start_visualization(app: str, *, model, node, composer, recorder=None) -> Callable[[], None]:
    """Diagnostics of every composite of ``model`` on ``node``; for an iTaSC application, the
    visualization process; ``recorder`` records the global topics. Returns what ends the process
    (also called when this process exits)."""
    from itasc_core.composition.model import walk

    from ..apps import resolve_app
    from ..model import load_application
    from .diagnostics import Diagnostics
    from .feed import FeedWriter, LatestSamples, display_topics
    from .node import DISPLAY_RATE, LATCHED_QOS, TF_QOS
    from itasc_msgs.msg import SolverStatus

    if recorder is not None:
        for topic, type_name in GLOBAL_TOPICS.items():
            recorder.record(topic, type_name, qos=LATCHED_QOS if topic == '/tf_static' else TF_QOS)
    composites = {m.name: path for path, m in walk(model)}
    solvers = [f'{path}/Solver/status' for path, m in walk(model) if any(e.name == 'Solver' for e in m.entities)]
    Diagnostics(node, app=model.name, composites=composites, timer=lambda: composer.timer,
                solvers=LatestSamples(node, dict.fromkeys(solvers, SolverStatus)))  # lives as long as the node
    path = resolve_app(app)
    if not _is_application(path):
        return lambda: None  # a composition model of the pattern itself: no robots to show
    topics = display_topics(load_application(path), f'/{model.name}')
    process = subprocess.Popen([sys.executable, '-m', 'itasc_bringup.visualization.node', str(path.resolve()),
                                '--feed'], stdin=subprocess.PIPE, stdout=subprocess.DEVNULL,
                               preexec_fn=_end_with_parent)
    feed = FeedWriter(node, LatestSamples(node, topics), process.stdin.fileno(), rate=DISPLAY_RATE)

    def end() -> None:
        feed.close()
        if process.poll() is None:
            process.terminate()
            try:
                process.wait(timeout=5.0)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        process.stdin.close()  # nothing is buffered in it: the feed writes to its descriptor
    atexit.register(end)
    return end

"""Seeing a run (issue #13): ``robot_description``, TF, markers and ``/diagnostics``.

A tool concern, not part of the application: like the recorder and the status line it observes
the composites through their topics, so it lives in itasc_bringup next to them, never in the
Composition Pattern's packages (paper §3.1: an entity knows its own composite only). The
bootstrap calls :func:`start_visualization` once the root composite is up: diagnostics on its own
node (they read the Timer), robot_description, TF and markers in a process of their own
(:mod:`.node`), off the control path. Neither subscribes to a topic the tick publishes: they take
the newest samples of the output ports in this process when they draw (:mod:`.feed`), so the
control loop pays nothing per tick for them.

The visualization process runs at a lower CPU priority than the application
(:data:`DISPLAY_NICENESS`, and Linux's ``SCHED_IDLE`` policy): where every core is busy, the display
waits, not the control loop.

The visualization process is a new interpreter: on a loaded 2-core machine its imports take
seconds. It starts with the bring-up and imports meanwhile, but joins DDS only once it is told to
(:meth:`Visualization.join`: the bootstrap does when the root is Running, and at the latest when
the run ends): a participant present during the bring-up slows it down (:mod:`.feed`). A recording
shows the run in 3-D from the file alone, so the bootstrap waits, before it closes a recording,
until the scene was drawn once (:meth:`Visualization.drawn`), at most :data:`FIRST_DRAWING_TIMEOUT`
after the process joined.
"""

from __future__ import annotations

import atexit
import os
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import yaml

if TYPE_CHECKING:
    from .feed import FeedWriter

__all__ = ['start_visualization', 'Visualization', 'GLOBAL_TOPICS', 'FIRST_DRAWING_TIMEOUT', 'DISPLAY_NICENESS']

#: Topics outside the application's namespace a recording must hold (type, QoS name).
GLOBAL_TOPICS = {'/tf': 'tf2_msgs/msg/TFMessage', '/tf_static': 'tf2_msgs/msg/TFMessage',
                 '/diagnostics': 'diagnostic_msgs/msg/DiagnosticArray'}


#: How long after its start the visualization process may take to draw the scene once (seconds).
FIRST_DRAWING_TIMEOUT = 10.0
#: How much lower the visualization process's CPU priority is than the bootstrap's (``nice``). Its
#: drawing (~5 ms of a core at 30 Hz) took the core the tick was due on: ``approach_object`` at
#: 1 kHz on a 2-core VM, three pairs of 20 s runs, dropped 165/319/187 ticks at the same priority,
#: 116/42/36 at +10 (tick p99 1.11-1.25 ms -> 0.97-1.11 ms). It also runs under ``SCHED_IDLE``
#: (a weight of 3 against the 110 of nice +10): a thread that spins between ticks is an ordinary
#: one, and the display's start (~2 s of imports) and drawing still took its core now and then;
#: ``--record`` at 1 kHz, three alternating pairs of 20 s runs: 976.4/986.9/979.8 -> 998.5/995.3/
#: 998.3 Hz, ticks dropped 476/265/409 -> 32/95/39, tick p99 0.92-1.00 -> 0.83-0.86 ms.
DISPLAY_NICENESS = 10


@dataclass
class Visualization:
    """The visualization of a run: ``join()`` lets its process join DDS and draw, ``end()`` ends it;
    ``drawn(recorder)`` says whether ``recorder`` holds the scene (``/tf_static``, ``/tf`` and the
    markers) or never will (no process, it died, or it is past :data:`FIRST_DRAWING_TIMEOUT`)."""

    end: Callable[[], None]
    process: subprocess.Popen | None = None
    markers: str | None = None
    feed: FeedWriter | None = None
    #: when it was told to join (``time.monotonic()``), None before
    joined_at: float | None = None

    def join(self) -> None:
        """The application is Running (or its run ends): the process may join DDS and draw."""
        if self.feed is not None and self.joined_at is None:
            self.joined_at = time.monotonic()
            self.feed.start()

    def missing(self, recorder) -> list[str]:
        """The topics of the scene (the markers, ``/tf``, ``/tf_static``) that ``recorder`` holds
        no message of; none without a visualization (a composition model of the pattern itself)."""
        if self.markers is None:
            return []
        return [topic for topic in (self.markers, '/tf', '/tf_static') if recorder.last(topic) is None]

    def drawn(self, recorder) -> bool:
        if self.process is None or self.markers is None or self.process.poll() is not None:
            return True
        if self.joined_at is None or time.monotonic() - self.joined_at > FIRST_DRAWING_TIMEOUT:
            return True
        return not self.missing(recorder)


def _is_application(path) -> bool:
    with open(path, encoding='utf-8') as stream:
        data = yaml.safe_load(stream)
    return isinstance(data, dict) and 'application' in data


def start_visualization(app: str, *, model, node, composer, recorder=None, observers=(),
                        states=None) -> Visualization:
    """Diagnostics of every composite of ``model`` on ``node``; for an iTaSC application, the
    visualization process; ``recorder`` records the global topics and the markers; what the
    ``observers`` of the process already read over DDS is not read again (:class:`.feed.LatestSamples`),
    nor the composites' states that ``states`` hands over (:class:`.diagnostics.Diagnostics`).
    Its ``end()`` is also called when this process exits."""
    from itasc_core.composition.model import walk

    from ..apps import resolve_app
    from ..model import load_application
    from .diagnostics import Diagnostics
    from .feed import FeedWriter, LatestSamples, display_topics
    from .node import DISPLAY_RATE, LATCHED_QOS, TF_QOS, markers_topic
    from itasc_core.communication.qos import DATA_QOS
    from itasc_msgs.msg import SolverStatus

    if recorder is not None:
        for topic, type_name in GLOBAL_TOPICS.items():
            recorder.record(topic, type_name, qos=LATCHED_QOS if topic == '/tf_static' else TF_QOS)
    composites = {m.name: path for path, m in walk(model)}
    solvers = [f'{path}/Solver/status' for path, m in walk(model) if any(e.name == 'Solver' for e in m.entities)]
    Diagnostics(node, app=model.name, composites=composites, timer=lambda: composer.timer,  # lives as long as the node
                solvers=LatestSamples(node, dict.fromkeys(solvers, SolverStatus), observers=observers), states=states)
    path = resolve_app(app)
    if not _is_application(path):
        return Visualization(end=lambda: None)  # a composition model of the pattern itself: no robots to show
    topics = display_topics(load_application(path), f'/{model.name}')
    markers = markers_topic(f'/{model.name}')
    if recorder is not None:
        recorder.record(markers, 'visualization_msgs/msg/MarkerArray', qos=DATA_QOS)
    # No preexec_fn: DDS runs threads in this process by now, and a child forked from a threaded
    # process may deadlock before exec (Python's subprocess documentation); the display follows
    # this process itself (``--parent``) and is given its lower priority from here. A session of
    # its own: a terminal's Ctrl-C is this process's to answer (it ends the display with SIGTERM);
    # one that reached the display while it still loaded (slower to start next to real-time
    # ticking threads) printed a KeyboardInterrupt traceback.
    process = subprocess.Popen([sys.executable, '-m', 'itasc_bringup.visualization.node', str(path.resolve()),
                                '--feed', '--parent', str(os.getpid())], stdin=subprocess.PIPE,
                               stdout=subprocess.DEVNULL, start_new_session=True)
    os.setpriority(os.PRIO_PROCESS, process.pid, min(19, os.getpriority(os.PRIO_PROCESS, 0) + DISPLAY_NICENESS))
    if hasattr(os, 'SCHED_IDLE'):  # Linux; the threads it starts inherit the policy
        os.sched_setscheduler(process.pid, os.SCHED_IDLE, os.sched_param(0))
    feed = FeedWriter(node, LatestSamples(node, topics, observers=observers), process.stdin.fileno(),
                      rate=DISPLAY_RATE)

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
    return Visualization(end=end, process=process, markers=markers, feed=feed)

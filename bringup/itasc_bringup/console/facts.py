"""What a run did, as a robot programmer asks it (paper §4.1 Tasks, §6.1 life-cycle and Running sub-FSM).

:class:`RunFacts` accumulates, from the messages a run publishes, what the console shows live and
what the summary reports at the end: the state of every composite, the path of every Running
sub-FSM with the time of each transition, each Task's error (an equality Task) or its distance
against its bounds (an inequality Task: ``output[0]`` against ``d_min``/``d_max``), the Solver's
status, and the Timer's tick times. It holds no ROS objects: :mod:`.watch` feeds it.

Its memory does not grow with the length of the run: per Task it keeps the figures the summary
reports, updated at each tick, and the latest values the live view draws; tick and solve times are
a :class:`~.distribution.Distribution`.

Times of the sub-FSM path are the Coordinators' own stamps, counted from the first composite that
reached ``Active.Run.Running``; a Task's time to converge is counted in its own tick stamps from
its first tick. A recording holds the same messages, so the same figures follow from it.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

from .distribution import Distribution

__all__ = ['TaskSpec', 'TaskTrace', 'Transition', 'RunFacts', 'Settling', 'task_specs', 'SETTLING_BAND', 'RECENT']

#: A Task has converged once its error stays within this fraction of its peak (2 % settling time).
SETTLING_BAND = 0.02
TASK_STATE = 'itasc_msgs/msg/TaskState'
SOLVER_STATUS = 'itasc_msgs/msg/SolverStatus'
RUNNING = 'Active.Run.Running'
#: How many of the latest ticks (and of an inequality Task's distances) the live view draws from.
RECENT = 2000


@dataclass(frozen=True)
class TaskSpec:
    """A Task of the model: its name, its TaskState topic and, for an inequality, its bounds."""

    name: str
    topic: str
    inequality: bool = False
    lower: float = -math.inf
    upper: float = math.inf


def task_specs(model, *, namespace: str) -> list[TaskSpec]:
    """Every Task of the composition ``model``: a composite publishing ``<ns>/Rows/state``, with
    the bounds of its inequality (the ``lower``/``upper`` of the entity marked ``inequality``)."""
    from itasc_core.composition.model import walk

    from ..recording.topics import data_flow_topics
    topics = [t for t, kind in data_flow_topics(model, namespace=namespace).items() if kind == TASK_STATE]
    composites = dict(walk(model, namespace.rsplit('/', 1)[0]))
    specs = []
    for topic in topics:
        owner = composites.get(topic.removesuffix('/Rows/state'))
        name = owner.name if owner else topic.split('/')[-3]
        bounds = [e.parameters for e in (owner.entities if owner else []) if e.parameters.get('inequality')]
        if bounds:
            lower, upper = (float(bounds[0].get(k, [d])[0]) for k, d in (('lower', -math.inf), ('upper', math.inf)))
            specs.append(TaskSpec(name, topic, inequality=True, lower=lower, upper=upper))
        else:
            specs.append(TaskSpec(name, topic))
    return specs


class Settling:
    """A Task's settling time, updated per tick: the seconds from its first tick until its error
    stays within ``band`` of its peak so far; None while the latest value is still outside, 0 if
    nothing ever left the band.

    Only the latest value outside the band matters, and a new peak is itself outside it (the band
    is a fraction of the peak), so no earlier value is needed when the peak grows.
    """

    def __init__(self, *, band: float = SETTLING_BAND) -> None:
        self.band = band
        self._first: float | None = None
        self.peak = -math.inf
        self._outside = False        # some value left the band
        self._latest_outside = False  # ... and it is the latest value
        self._back_at: float | None = None  # the stamp of the value after the latest outside one

    def add(self, t: float, value: float) -> None:
        if self._first is None:
            self._first = t
        if self._latest_outside:
            self._back_at, self._latest_outside = t, False
        self.peak = max(self.peak, value)
        if value > self.band * self.peak:
            self._outside = self._latest_outside = True

    @property
    def after(self) -> float | None:
        if self._first is None or self._latest_outside:
            return None
        return self._back_at - self._first if self._outside and self._back_at is not None else 0.0


@dataclass
class TaskTrace:
    """What one Task's ticks showed: how many, its latest and peak error norm, its settling time,
    and for an inequality its latest distance ``output[0]``, its smallest margin to the bounds and
    its latest :data:`RECENT` distances."""

    spec: TaskSpec
    ticks: int = 0
    final_error: float | None = None
    final_distance: float | None = None
    min_margin: float | None = None
    recent_distance: deque = field(default_factory=lambda: deque(maxlen=RECENT))
    settling: Settling = field(default_factory=Settling)

    def add(self, sample) -> None:
        """One tick of the Task (an ``itasc_msgs/TaskState`` sample)."""
        self.ticks += 1
        self.final_error = sample.error_norm
        self.settling.add(sample.t, sample.error_norm)
        if self.spec.inequality and len(sample.output):
            distance = float(sample.output[0])
            self.final_distance = distance
            self.recent_distance.append(distance)
            margin = self.margin(distance)
            self.min_margin = margin if self.min_margin is None else min(self.min_margin, margin)

    def margin(self, distance: float) -> float:
        """How far ``distance`` is inside the bounds (negative: violated)."""
        return min(distance - self.spec.lower, self.spec.upper - distance)

    @property
    def peak_error(self) -> float:
        return max(self.settling.peak, 0.0)

    @property
    def converged_after(self) -> float | None:
        return None if self.spec.inequality else self.settling.after


@dataclass(frozen=True)
class Transition:
    """A composite entered ``state`` (its Coordinator's stamp ``stamp``, s) because of ``event``."""

    composite: str
    state: str
    event: str
    stamp: float


class RunFacts:
    """Everything the console and the summary say about a run, from its messages."""

    def __init__(self, *, composites: dict[str, str], tasks: list[TaskSpec]) -> None:
        """``composites``: name -> namespace, parents first; ``tasks``: the model's Tasks."""
        self.composites = composites
        self.states: dict[str, str] = dict.fromkeys(composites, '-')
        self.transitions: list[Transition] = []
        self.tasks: dict[str, TaskTrace] = {spec.name: TaskTrace(spec) for spec in tasks}
        self.solver_status = ''
        self.running_since: float | None = None   # stamp of the first composite in Running
        self.ticks = Distribution()                  # the Timer's tick durations (s)
        self.recent_ticks: deque = deque(maxlen=RECENT)
        self.dropped_ticks = 0                       # due while the Timer was too far behind to catch up
        self.solve_times = Distribution()            # the Solver's solve times (s)
        #: Per Solver topic, its steps in the counted window: [count, first t, last t] (program time).
        self._steps: dict[str, list[float]] = {}
        self._steps_window = (math.inf, math.inf)   # opened by count_ticks(since=..., origin=...)
        self._last_tick = -math.inf
        self._tick_span: list[float] = []          # first and last tick (monotonic)
        #: The ticks that count (monotonic): from the root's Running to the stop (see :meth:`count_ticks`).
        self._ticks_until = math.inf
        self._dropped_before = 0
        self._dropped_until: int | None = None

    # -- feeding ------------------------------------------------------------------------------

    def on_state(self, msg) -> Transition:
        stamp = msg.stamp.sec + msg.stamp.nanosec * 1e-9
        transition = Transition(msg.composite, msg.state, msg.event, stamp)
        self.states[msg.composite] = msg.state
        self.transitions.append(transition)
        if self.running_since is None and msg.state.startswith(RUNNING):
            self.running_since = stamp
        return transition

    def unseen(self) -> list[str]:
        """The composites of which no state was received yet."""
        return [name for name, state in self.states.items() if state == '-']

    def on_task(self, task: str, msg) -> None:
        self.tasks[task].add(msg)

    def on_solver(self, msg, *, topic: str = '') -> None:
        """One step of the Solver publishing on ``topic`` (an ``itasc_msgs/SolverStatus`` sample)."""
        self.solver_status = msg.status
        self.solve_times.add(msg.solve_time)
        if self._steps_window[0] <= msg.t <= self._steps_window[1]:
            steps = self._steps.get(topic)
            if steps is None:
                self._steps[topic] = [1, msg.t, msg.t]
            else:  # a sample that came late may be older than the last one
                steps[0] += 1
                steps[1], steps[2] = min(steps[1], msg.t), max(steps[2], msg.t)

    def count_ticks(self, *, since: float | None = None, until: float | None = None, dropped: int,
                    origin: float | None = None) -> None:
        """The run's tick figures are those of the ticks that start after ``since`` (the root is
        Running) and not after ``until`` (the stop was commanded), monotonic; ``dropped``: how many
        ticks the Timer had dropped by then. Ticks counted before ``since`` are forgotten (the
        Timer's window still holds those after it); the bring-up and the stop of a large program
        hold the thread for 0.1-0.3 s at a time, which is not the rate it runs at. ``origin``: the
        root Timer's (``time.monotonic()`` at program time 0), so that the Solvers' steps, stamped
        with the tick's program time wherever they ran, are counted over the same window."""
        if since is not None:
            self.ticks, self._tick_span = Distribution(), []
            self._last_tick, self._dropped_before = since, dropped
            if origin is not None:
                self._steps, self._steps_window = {}, (since - origin, math.inf)
        if until is not None:
            self._ticks_until, self._dropped_until = until, dropped
            if origin is not None:
                self._steps_window = (self._steps_window[0], until - origin)

    def on_ticks(self, stamps, durations, *, dropped: int = 0) -> None:
        """The Timer's latest ticks (monotonic start, duration; oldest first): those not seen yet
        are kept. Walks back from the newest, so a poll costs what is new. ``dropped``: how many
        ticks the Timer has dropped so far."""
        self.dropped_ticks = (dropped if self._dropped_until is None else self._dropped_until) - self._dropped_before
        new = []
        for stamp, duration in zip(reversed(stamps), reversed(durations)):
            if stamp <= self._last_tick:
                break
            if stamp <= self._ticks_until:
                new.append((stamp, duration))
        if stamps and stamps[-1] > self._last_tick:
            self._last_tick = stamps[-1]  # seen, counted or not (after the stop)
        if new:
            new.reverse()
            for _, duration in new:
                self.ticks.add(duration)
                self.recent_ticks.append(duration)
            self._tick_span = [self._tick_span[0] if self._tick_span else new[0][0], new[-1][0]]

    # -- what it says -------------------------------------------------------------------------

    @staticmethod
    def sub_state(state: str) -> str | None:
        """The Running sub-FSM state in a fully-qualified state, if any."""
        return state.removeprefix(RUNNING + '.') if state.startswith(RUNNING + '.') else None

    def paths(self) -> dict[str, list[tuple[str, float]]]:
        """Per composite with a Running sub-FSM: ``[(sub-state, seconds from Running), ...]``."""
        out: dict[str, list[tuple[str, float]]] = {name: [] for name in self.composites}  # parents first
        for tr in self.transitions:
            sub = self.sub_state(tr.state)
            if sub is not None:
                out[tr.composite].append((sub, tr.stamp - (self.running_since or tr.stamp)))
        return {name: path for name, path in out.items() if path}

    def achieved_rate(self) -> float:
        n = self.ticks.count
        span = self._tick_span[1] - self._tick_span[0] if self._tick_span else 0.0
        return (n - 1) / span if n > 1 and span > 0 else 0.0

    def solver_rate(self) -> float | None:
        """The Solver's steps a second over the counted window (of several Solvers, the slowest):
        with ``--deploy per-composite``, how often the program's own process computed. None before
        two steps."""
        rates = [(n - 1) / (last - first) for n, first, last in self._steps.values() if n > 1 and last > first]
        return min(rates) if rates else None

    def tick_percentile(self, q: float) -> float | None:
        """The ``q``-th percentile of the tick times (s), nearest rank; None without ticks."""
        return self.ticks.percentile(q)

    def solve_percentile(self, q: float) -> float | None:
        """The ``q``-th percentile of the Solver's solve times (s); None without any."""
        return self.solve_times.percentile(q)


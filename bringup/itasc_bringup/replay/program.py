"""Running the application's programs offline, tick by tick, on recorded inputs.

The program composites (the root's child composites) are brought up as the bootstrap's root
Composer brings them up with ``--deploy single`` (:func:`itasc_core.composition.composer.bring_up`),
with the real entities, in a ROS domain of their own. In place of the root composite:

- its Drivers and Sensors: output ports of the same topics, which write the recorded samples
  (sent before a tick began) before each tick; the programs' exported inputs are bound to them as
  the root's Composer binds them;
- its Timer: each recorded tick ``t`` triggers the programs' Schedulers in the root's order;
- its Coordinator and anyone else outside the programs (an operator, another node through an
  ``outside_events`` entity): their recorded events to the programs are raised again, in the gap
  they were sent in.

Between two ticks the executor runs everything that is ready and the Coordinators take their
buffered events, until nothing is left, with :class:`.timing.EventTiming` deciding in which gap
each event is handled.
"""

from __future__ import annotations

import time
from collections import defaultdict
from dataclasses import dataclass, field
from typing import Any

import rclpy
from itasc_core.communication.event_names import is_addressed_to
from itasc_core.communication.events import EventRaiser
from itasc_core.communication.ports import InputPort, OutputPort, PortSpec
from itasc_core.communication.samples import as_message, as_sample
from itasc_core.composition.composer import Composer, bring_up
from itasc_core.composition.deployment import Runtime
from itasc_core.composition.model import OUTSIDE_EVENTS, CompositeModel
from itasc_core.composition.resolve import port_of
from itasc_core.coordination.coordinator import Coordinator
from itasc_core.entity import CompositeContext
from rclpy.executors import ShutdownException, SingleThreadedExecutor, TimeoutException

from ..recording.topics import data_flow_topics
from .dds import private_domain, select_profile
from .recording import RecordedEvent, Recording, ReplayError, is_stamped, nanoseconds
from .timing import EventTiming

__all__ = ['Plan', 'plan_of', 'Replayed', 'replay_programs', 'running_path', 'TASK_STATE', 'TASK_ROWS']

#: The outputs of every Task that a replay compares: its error, and its rows for the Solver.
TASK_STATE = 'itasc_msgs/msg/TaskState'
TASK_ROWS = 'itasc_msgs/msg/ConstraintRows'


@dataclass(frozen=True)
class Plan:
    """What a replay of ``model`` runs and compares, from the model alone."""

    root: CompositeContext
    programs: list[CompositeModel]
    #: program -> topic of its exported ``command``
    commands: dict[str, str]
    #: topic -> port of a Driver's or Sensor's output that feeds a program
    feeds: dict[str, PortSpec]
    #: (program, exported input, topic it is bound to)
    bindings: list[tuple[str, str, str]]
    #: every output topic of the programs with stamped messages -> its message type
    outputs: dict[str, str]

    def of_kind(self, kind: str) -> list[str]:
        """The output topics of message type ``kind`` (e.g. every Task's ``itasc_msgs/msg/TaskState``)."""
        return [topic for topic, k in self.outputs.items() if k == kind]

    def inside(self, source: str) -> bool:
        """Whether the entity ``source`` (a node's full name) is one of a program's that the replay
        runs again; not an ``outside_events`` entity: what it raises came from outside the
        application (another node's topic or service call)."""
        return source.rsplit('/', 1)[-1] != OUTSIDE_EVENTS \
            and any(source.startswith(self.root.child(p.name).namespace + '/') for p in self.programs)


def plan_of(model: CompositeModel) -> Plan:
    root = CompositeContext(name=model.name, namespace=f'/{model.name}')
    programs = [e for e in map(model.entity, model.schedule_order()) if isinstance(e, CompositeModel)]
    ports = {p.name: port_of(model, root.namespace, f'{p.name}.command')[0] for p in programs if 'command' in p.exports}
    if not ports:
        raise ReplayError(f'model {model.name} has no constraint-based program (no composite of its root '
                          "exports a 'command')")
    for name, spec in ports.items():  # the ticks are told by the stamps of the commands
        if not is_stamped(spec.msg_type_name):
            raise ReplayError(f"model {model.name}: {name}'s command ({spec.id}, {spec.msg_type_name}) carries no "
                              'stamp, so the recording cannot tell its ticks; itasc-replay replays programs whose '
                              "command is stamped, as a constraint-based program's Solver's is")
    commands = {name: spec.id for name, spec in ports.items()}
    names = {p.name for p in programs}
    feeds, bindings = {}, []
    for connection in model.connections:
        target, _, port = connection.target.partition('.')
        if target in names:
            spec, _ = port_of(model, root.namespace, connection.source)
            bindings.append((target, port, spec.id))
            if connection.source.partition('.')[0] not in names:
                feeds[spec.id] = spec
    outputs = {topic: kind for p in programs
               for topic, kind in data_flow_topics(p, namespace=root.child(p.name).namespace).items()
               if is_stamped(kind)}
    return Plan(root, programs, commands, feeds, bindings, outputs)


@dataclass
class Replayed:
    """What the replayed programs computed, per recorded tick (None: nothing at that tick)."""

    #: topic -> message per tick, for the commands and the Tasks' states and rows
    outputs: dict[str, list[Any]]
    #: composite -> the states of its Running sub-FSM it entered, in order
    paths: dict[str, list[str]]
    #: wall-clock seconds the ticks took
    seconds: float


def running_path(history: list[str]) -> list[str]:
    """The Running sub-states in a sequence of fully qualified states, repeats removed."""
    path: list[str] = []
    for state in history:
        if state.startswith('Active.Run.Running.') and (not path or path[-1] != state):
            path.append(state)
    return [state.removeprefix('Active.Run.Running.') for state in path]


@dataclass
class _Probe:
    """The first message of each stamp an output wrote, taken in this process."""

    port: InputPort | None = None
    by_stamp: dict[int, Any] = field(default_factory=dict)

    def take(self, sample: Any) -> None:
        msg = as_message(sample)
        self.by_stamp.setdefault(nanoseconds(msg), msg)


def replay_programs(plan: Plan, recording: Recording) -> Replayed:
    """Bring up the programs of ``plan`` and run them on ``recording``, tick by tick."""
    select_profile()
    rclpy.init(domain_id=private_domain())
    replay = None
    try:
        replay = _Replay(plan, recording)
        replay.runtime.events.gate = replay.timing
        return replay.run()
    finally:
        if replay is not None:
            replay.runtime.events.gate = None
            replay.destroy()
        rclpy.try_shutdown()


class _Replay:
    """The programs of ``plan``, their stand-ins for the root composite, and the stepping."""

    def __init__(self, plan: Plan, recording: Recording) -> None:
        self.plan, self.recording = plan, recording
        self.executor = SingleThreadedExecutor()  # its wait_for_ready_callbacks tells that nothing is ready
        self.runtime = Runtime(executor=self.executor, mode='single', namespace=plan.root.namespace)
        self.node = rclpy.create_node('replay', namespace=plan.root.namespace)
        self.executor.add_node(self.node)
        self.timing = EventTiming(recording, alive=lambda node: node in self.executor.get_nodes())
        self.coordinators: dict[str, Coordinator] = {}
        self.probes = {topic: _Probe() for topic in [*plan.commands.values(), *plan.of_kind(TASK_STATE),
                                                     *plan.of_kind(TASK_ROWS)]}
        self.feeds = {topic: OutputPort(self.node, spec) for topic, spec in plan.feeds.items()}
        self.unbound = list(plan.bindings)
        self.outside = _outside_events(plan, recording)
        self.raisers: dict[tuple[str, str], EventRaiser] = {}
        self.quiet_at = -1  # the events raised when the executor was last found with nothing ready
        self.composers: dict[str, Composer] = {}

    def run(self) -> Replayed:
        for program in self.plan.programs:
            self.composers[program.name] = bring_up(model=program, context=self.plan.root.child(program.name),
                                                    runtime=self.runtime)
        recording = self.recording
        inputs = sorted((sent, topic, msg) for topic in self.feeds for sent, msg in recording.samples.get(topic, []))
        fed = 0
        self.end_gap(-1)
        began = time.perf_counter()
        for k, t in enumerate(recording.ticks):
            while fed < len(inputs) and inputs[fed][0] < recording.starts[k]:  # sent before the tick began
                _, topic, msg = inputs[fed]
                self.feeds[topic].write(as_sample(msg))
                fed += 1
            self.connect_probes()
            self.timing.gap = k
            for program in self.plan.programs:
                self.composers[program.name].tick(t * 1e-9)
            self.end_gap(k)
        seconds = time.perf_counter() - began
        return Replayed(outputs={topic: [probe.by_stamp.get(t) for t in recording.ticks]
                                 for topic, probe in self.probes.items()},
                        paths={ns.rsplit('/', 1)[-1]: running_path([state for state, *_ in c.history])
                               for ns, c in self.coordinators.items()},
                        seconds=seconds)

    def end_gap(self, gap: int) -> None:
        """What happens between tick ``gap`` and the next: the program's events, then one by one
        those raised to it from outside."""
        self.timing.gap = gap
        self.settle()
        for event in self.outside.get(gap, []):
            raiser = self.raisers.get((event.topic, event.source))
            if raiser is None:
                raiser = EventRaiser(self.node, topic=event.topic, source=event.source)
                self.raisers[event.topic, event.source] = raiser
            raiser.raise_event(event.name, priority=event.priority, detail=event.detail)
            self.settle()

    def settle(self) -> None:
        """Hand over the events that are due and let the Coordinators take them, until no event is
        left to deliver."""
        while True:
            released = self.timing.release()
            self.runtime.events.flush()  # what this process raised reaches its listeners
            self.update_coordinators()
            if not released and self.runtime.events.raised == self.quiet_at:
                break
            self.quiet_at = self.runtime.events.raised
            self.spin_ready()
            self.runtime.reap()
        # the root's Composer binds the programs' inputs once they are deployed
        for program, port, topic in [b for b in self.unbound if self.composers[b[0]].scheduler is not None]:
            self.composers[program].bind_export(port, topic)
            self.unbound.remove((program, port, topic))

    def spin_ready(self) -> None:
        """Run callbacks until a wait finds none ready."""
        ran = True
        while ran:
            ran = False
            try:  # the callbacks one wait found, then TimeoutException
                while True:
                    handler, _, _ = self.executor.wait_for_ready_callbacks(timeout_sec=0)
                    handler()
                    handler.result()  # raises what the callback raised
                    ran = True
            except (TimeoutException, ShutdownException):
                pass

    def update_coordinators(self) -> None:
        """Every Coordinator takes its buffered events (its periodic update, stepped here)."""
        for entity in self.executor.get_nodes():
            if isinstance(entity, Coordinator):
                if entity.get_namespace() not in self.coordinators:
                    self.coordinators[entity.get_namespace()] = entity
                    for timer in entity.timers:  # the wall-clock update timer: stepped instead
                        timer.cancel()
                entity.update()

    def connect_probes(self) -> None:
        """Take the compared outputs in this process, as soon as they exist."""
        for topic, probe in self.probes.items():
            output = self.runtime.bus.lookup(topic)
            if probe.port is None and output is not None:
                probe.port = InputPort(self.node, output.spec, on_sample=probe.take)
                probe.port.connect(topic)

    def destroy(self) -> None:
        for entity in self.executor.get_nodes():
            self.executor.remove_node(entity)
            entity.destroy_node()


def _outside_events(plan: Plan, recording: Recording) -> dict[int, list[RecordedEvent]]:
    """The recorded events raised to the programs from outside them (the root's Coordinator, an
    operator, a test), by the gap they were sent in."""
    root_topic = plan.root.events_topic
    names = [p.name for p in plan.programs]
    found: dict[int, list[RecordedEvent]] = defaultdict(list)
    for event in recording.events:
        if plan.inside(event.source):
            continue
        to_program = any(event.topic.startswith(plan.root.child(n).namespace + '/') for n in names)
        if to_program or (event.topic == root_topic and any(is_addressed_to(n, event.name) for n in names)):
            found[recording.gap(event.sent)].append(event)
    return found

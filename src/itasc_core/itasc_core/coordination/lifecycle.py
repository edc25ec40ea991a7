"""The life-cycle FSM of a Composite Functional Entity (paper §6.1, Figs. 4, 5 and 6).

A plain-Python, *pure* event processor: it consumes event names and raises event names through a
callback; it never calls platform code. The ROS wrapper is :mod:`itasc_core.coordination.coordinator`.

States carry the paper's names, fully qualified with dots::

    Active.Configure.Configuring.{DeployEntities, ConfigureEntities}
    Active.Configure.Configured.{ConnectEntities, NotifyConfigured}
    Active.Start.{Starting, Started}
    Active.Run.{PreRunning, Running[.<application sub-FSM>]}
    Active.Stop.Stopping, Active.Stop.Stopped.{Disengage, CleanupComputation, Cleanup, NotifyStopped}
    Safety

Safety is entered from anywhere in Active on ``e_emergency``, on a failure report of this
composite's Composer, Configurator or Scheduler, when the parent entered Safety (it commands
``e_<child>_emergency`` to every child, so that no composite below one in Safety goes on
running), or on ``e_<c>_timeout``: the Coordinator raises it when a state on the way to Running
(DeployEntities, ConfigureEntities, ConnectEntities, Starting, PreRunning) waited longer than its
timeout for events of its own entities or children that did not come (a
child that never answers). Leaving it takes a reconfiguration (``e_<c>_configure``) or an
orderly stop. A reconfiguration commanded by the parent (which recovers, or reconfigures its
children) is driven on by the parent as at the first start; one this composite starts itself
(:meth:`LifecycleFsm.recover`, the operator's ``~/recover`` of a composite whose parent is not in
Safety) goes on through Start and Run to Running on its own, as the root does.

Every transition waits for a *set* of events (∀ in Fig. 5). Event memory (the rFSM extension)
records the events that arrived since the current state was entered and is cleared on every state
entry, so a transition fires as soon as all of its events are in memory, in whatever order and at
whatever moment they arrived.

We build the statechart with ``transitions``' HierarchicalMachine rather than by hand: it is a
well-kept, dictionary-driven statechart library, which is what the Running sub-FSM needs (it is
data from the application model, not code), and it gives entry callbacks and nested states with
parent-level transitions (Active → Safety from any sub-state). python-statemachine 3 declares
charts as classes, which fits data-driven charts less well.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterable

from transitions.extensions.nesting import HierarchicalMachine, NestedState

from ..communication import event_names as names
from ..communication.event_names import SAFETY_EVENT

__all__ = [
    'LifecycleFsm',
    'RunningFsmSpec',
    'RunningState',
    'RunningTransition',
    'Raise',
    'SAFETY_EVENT',
]

#: ``raise_event(name, to_parent)``: ``to_parent`` sends the event to the parent composite's event
#: topic (notifications such as ``e_<c>_configured``); otherwise to this composite's own topic.
Raise = Callable[[str, bool], None]


#: Events raised on entering a state: to this composite's entities ('own'), to every child's
#: Coordinator ('children'), or to the parent's Coordinator ('parent'), e.g. ``e_<composite>_deploy``.
_ENTRY_EVENTS: dict[str, tuple[tuple[str, str], ...]] = {
    'DeployEntities': (('own', names.DEPLOY),),
    'ConfigureEntities': (('own', names.CONFIGURE_ENTITIES), ('children', names.CONFIGURE)),
    'ConnectEntities': (('own', names.CONNECT),),
    'NotifyConfigured': (('parent', names.CONFIGURED),),
    'Starting': (('own', names.SCHEDULER_INITIALIZE), ('children', names.START)),
    'Started': (('parent', names.STARTED),),
    'PreRunning': (('children', names.RUN), ('own', names.SCHEDULER_ACTIVATE)),
    'Running': (('parent', names.RUNNING),),
    'Stopping': (('children', names.STOP),),
    'Disengage': (('own', names.DISENGAGE),),
    'CleanupComputation': (('own', names.CLEANUP_COMPUTATION),),
    'Cleanup': (('own', names.CLEANUP),),
    'NotifyStopped': (('parent', names.STOPPED),),
    'Safety': (('own', names.SAFETY), ('children', names.EMERGENCY)),
}


#: The states on the way to Running that wait for the composite's own entities or children.
_STARTUP_WAITS = frozenset({'DeployEntities', 'ConfigureEntities', 'ConnectEntities', 'Starting', 'PreRunning'})


class _DottedState(NestedState):
    separator = '.'


class _Machine(HierarchicalMachine):
    state_cls = _DottedState


@dataclass(frozen=True)
class RunningState:
    """A state of the application-specific Running sub-FSM and the events it raises on entry."""

    name: str
    raise_on_entry: tuple[str, ...] = ()


@dataclass(frozen=True)
class RunningTransition:
    source: str
    target: str
    #: All of these events must have arrived since ``source`` was entered.
    events: tuple[str, ...]


@dataclass(frozen=True)
class RunningFsmSpec:
    """The Running sub-FSM plugged in from the application model (paper §6.2)."""

    initial: str
    states: tuple[RunningState, ...]
    transitions: tuple[RunningTransition, ...] = ()


@dataclass
class _Transition:
    source: str
    target: str
    requires: frozenset[str]


class LifecycleFsm:
    """The life-cycle FSM of one composite.

    :param composite: name of the composite (appears in event names, e.g. ``e_<composite>_start``).
    :param children: names of the child composites whose Coordinators this one coordinates.
    :param is_root: the root Coordinator moves from an ``-ed`` to the next ``-ing`` state on its own.
    :param raise_event: called for every event this Coordinator raises.
    :param on_state: called with ``(new_state, previous_state, event)`` after every state change.
    :param running: the application-specific Running sub-FSM, if any.
    :param safety_to_parent: events raised to the parent when this composite enters Safety
        (the application decides what propagates).
    """

    def __init__(
        self,
        *,
        composite: str,
        children: Iterable[str] = (),
        is_root: bool = False,
        raise_event: Raise,
        on_state: Callable[[str, str, str], None] | None = None,
        running: RunningFsmSpec | None = None,
        safety_to_parent: Iterable[str] = (),
    ) -> None:
        self.composite = composite
        self.children = tuple(children)
        self.is_root = is_root
        self._raise = raise_event
        self._on_state = on_state
        self._running = running
        self._safety_to_parent = tuple(safety_to_parent)
        #: Event memory: the events that arrived since the current state was entered.
        self._memory: set[str] = set()
        self._last_event = ''
        self._entered: list[str] = []
        self.state = 'Init'
        self._transitions: list[_Transition] = []
        self._adopted: dict[str, str] = {}
        #: Recovering on its own (not commanded by the parent): moves from -ed to -ing by itself.
        self._self_driven = False
        self._add_transitions()
        self._stopping = next(t for t in self._transitions if t.source == 'Active.Stop.Stopping')
        self._relevant = {SAFETY_EVENT}.union(*(t.requires for t in self._transitions))
        self._relevant |= {self.event(names.STOPPED, k) for k in self.children}
        self._machine = _Machine(
            model=self,
            states=self._states(),
            initial='Init',
            auto_transitions=False,
            ignore_invalid_triggers=True,
            send_event=True,
            model_attribute='state',
            after_state_change=self._after_state_change,
        )
        for t in self._transitions:
            self._machine.add_transition(
                '_evaluate', t.source, t.target, conditions=[self._guard(t)])

    # -- event names ------------------------------------------------------------------------------

    def event(self, suffix: str, name: str | None = None) -> str:
        return names.event(name or self.composite, suffix)

    def is_relevant(self, event: str) -> bool:
        """Whether this FSM reacts to ``event`` (anything else is ignored without cost)."""
        return event in self._relevant

    def relevant_events(self) -> list[str]:
        """Every event some state of this FSM reacts to."""
        return sorted(self._relevant)

    def running_events(self) -> set[str]:
        """The events the application's Running sub-FSM moves on (its transitions' events)."""
        return {e for t in (self._running.transitions if self._running is not None else ()) for e in t.events}

    def reacts_now(self, event: str) -> bool:
        """Whether a transition out of the current state (or one of its parents) needs ``event``."""
        return any(event in t.requires and (self.state == t.source or self.state.startswith(t.source + '.'))
                   for t in self._transitions)

    # -- recovery from Safety -----------------------------------------------------------------------

    def recover(self) -> bool:
        """Leave Safety by reconfiguration (paper §6.1), on this composite's own initiative: Safety
        -> Active.Configure, and on through Start and Run to Running without waiting for commands
        of the parent, which is not in Safety and already runs. Returns whether it left Safety."""
        if self.state != 'Safety':
            return False
        self._self_driven = not self.is_root  # the root drives itself anyway
        return self.process(self.event(names.CONFIGURE))

    # -- run-time re-composition (:mod:`..composition.steps`) ------------------------------------------

    def adopt(self, child: str) -> None:
        """A child composite added while this one runs (paper §6.1: a new Task goes through the
        life-cycle until Running while the rest keeps running): command it on through Configure,
        Start and Run, and wait for it when stopping."""
        if child in self.children:
            return
        self.children = self.children + (child,)
        self._stopping.requires = self._stopping.requires | {self.event(names.STOPPED, child)}
        self._relevant |= {self.event(suffix, child) for suffix in names.NOTIFICATIONS}
        self._adopted[child] = names.CONFIGURE
        self._raise(self.event(names.CONFIGURE, child), False)

    def release(self, child: str) -> None:
        """A child composite removed while this one runs: command it to stop (it stops in order,
        then its parent's Composer destroys it), and no longer coordinate it."""
        if child not in self.children:
            return
        self.children = tuple(c for c in self.children if c != child)
        self._stopping.requires = self._stopping.requires - {self.event(names.STOPPED, child)}
        self._adopted.pop(child, None)
        self._raise(self.event(names.STOP, child), False)

    def _drive_adopted(self, event: str) -> None:
        for child, step in self._adopted.items():
            if step == names.CONFIGURE and event == self.event(names.CONFIGURED, child):
                self._adopted[child] = names.START
                self._raise(self.event(names.START, child), False)
            elif step == names.START and event == self.event(names.STARTED, child):
                self._adopted[child] = names.RUN
                self._raise(self.event(names.RUN, child), False)
            elif step == names.RUN and event == self.event(names.RUNNING, child):
                self._adopted[child] = names.RUNNING

    # -- processing ---------------------------------------------------------------------------------

    def process(self, event: str) -> bool:
        """Feed one event; returns True if it changed the state."""
        self._memory.add(event)
        self._last_event = event
        if self._adopted:
            self._drive_adopted(event)
        moved = False
        # Bounded: every pass enters a new state; transitions that need no event chain on.
        for _ in range(64):
            if not self._evaluate():  # type: ignore[attr-defined]  # a trigger transitions adds to the model
                return moved
            moved = True
        raise RuntimeError(f'{self.composite}: life-cycle FSM does not settle in {self.state}')

    def _guard(self, transition: _Transition) -> Callable[..., bool]:
        return lambda _event_data: transition.requires <= self._memory

    def _after_state_change(self, event_data) -> None:
        previous = event_data.transition.source
        event, self._last_event = self._last_event, ''
        if self._on_state is not None:
            self._on_state(self.state, previous, event)
        for path in self._entered:
            self._entry_actions(path)
        self._entered = []

    def _entry(self, path: str) -> Callable[..., None]:
        def on_enter(_event_data) -> None:
            # Event memory is cleared on every state entry (rFSM event-memory extension).
            self._memory.clear()
            self._entered.append(path)
        return on_enter

    # -- structure --------------------------------------------------------------------------------

    def _states(self) -> list:
        """The statechart of Figs. 4 and 5, with an entry callback on every state."""
        return [self._with_entries(s, '') for s in self._chart()]

    def _with_entries(self, state, parent: str) -> dict:
        spec = {'name': state} if isinstance(state, str) else dict(state)
        path = f"{parent}.{spec['name']}" if parent else spec['name']
        spec['on_enter'] = [self._entry(path)]
        if 'children' in spec:
            spec['children'] = [self._with_entries(c, path) for c in spec['children']]
        return spec

    def _chart(self) -> list:
        running: dict = {'name': 'Running'}
        if self._running is not None:
            running['children'] = [s.name for s in self._running.states]
            running['initial'] = self._running.initial
        return [
            'Init',
            {'name': 'Active', 'initial': 'Configure', 'children': [
                {'name': 'Configure', 'initial': 'Configuring', 'children': [
                    {'name': 'Configuring', 'initial': 'DeployEntities',
                     'children': ['DeployEntities', 'ConfigureEntities']},
                    {'name': 'Configured', 'initial': 'ConnectEntities',
                     'children': ['ConnectEntities', 'NotifyConfigured']},
                ]},
                {'name': 'Start', 'initial': 'Starting', 'children': ['Starting', 'Started']},
                {'name': 'Run', 'initial': 'PreRunning', 'children': ['PreRunning', running]},
                {'name': 'Stop', 'initial': 'Stopping', 'children': [
                    'Stopping',
                    {'name': 'Stopped', 'initial': 'Disengage', 'children': [
                        'Disengage', 'CleanupComputation', 'Cleanup', 'NotifyStopped']},
                ]},
            ]},
            'Safety',
        ]

    def _add_transitions(self) -> None:
        e, kids = self.event, self.children
        configured = 'Active.Configure.Configured'

        def add(source: str, target: str, *requires: str) -> None:
            self._transitions.append(_Transition(source, target, frozenset(requires)))

        # Safety first: it has priority over every other transition of Active.
        for failure in (names.DEPLOY_FAILED, names.CONFIGURE_FAILED, names.CONNECT_FAILED, names.SCHEDULER_FAILED):
            add('Active', 'Safety', e(failure))
        add('Active', 'Safety', SAFETY_EVENT)
        add('Active', 'Safety', e(names.EMERGENCY))  # the parent entered Safety: so does every child
        add('Active', 'Safety', e(names.TIMEOUT))  # a start-up state waited too long (see STARTUP_TIMEOUT)
        add('Init', 'Active', e(names.CONFIGURE))
        add('Safety', 'Active', e(names.CONFIGURE))  # leaving Safety requires reconfiguration
        add('Safety', 'Active.Stop', e(names.STOP))  # an orderly teardown is still possible

        add('Active.Configure.Configuring.DeployEntities', 'Active.Configure.Configuring.ConfigureEntities',
            e(names.DEPLOYED))
        add('Active.Configure.Configuring.ConfigureEntities', configured,
            e(names.ENTITIES_CONFIGURED), *(e(names.CONFIGURED, k) for k in kids))
        add(f'{configured}.ConnectEntities', f'{configured}.NotifyConfigured', e(names.CONNECTED))
        own = () if self.is_root else (e(names.START),)
        add(f'{configured}.NotifyConfigured', 'Active.Start', *own)
        add('Active.Start.Starting', 'Active.Start.Started',
            e(names.SCHEDULER_INITIALIZED), *(e(names.STARTED, k) for k in kids))
        own = () if self.is_root else (e(names.RUN),)
        add('Active.Start.Started', 'Active.Run', *own)
        add('Active.Run.PreRunning', 'Active.Run.Running',
            e(names.SCHEDULER_ACTIVATED), *(e(names.RUNNING, k) for k in kids))
        if self._running is not None:
            for t in self._running.transitions:
                add(f'Active.Run.Running.{t.source}', f'Active.Run.Running.{t.target}', *t.events)
        # A parent reconfiguring (e.g. after its own Safety) reconfigures its children too.
        add('Active.Start', 'Active', e(names.CONFIGURE))
        add('Active.Run', 'Active', e(names.CONFIGURE))
        add('Active.Configure', 'Active.Stop', e(names.STOP))
        add('Active.Start', 'Active.Stop', e(names.STOP))
        add('Active.Run', 'Active.Stop', e(names.STOP))
        # Stopping waits for the children that were commanded to configure (see _entry_actions): a
        # stop during DeployEntities finds children that never started, with nothing to stop.
        add('Active.Stop.Stopping', 'Active.Stop.Stopped')
        stopped = 'Active.Stop.Stopped'
        add(f'{stopped}.Disengage', f'{stopped}.CleanupComputation', e(names.DISENGAGED))
        add(f'{stopped}.CleanupComputation', f'{stopped}.Cleanup', e(names.COMPUTATION_CLEANED))
        add(f'{stopped}.Cleanup', f'{stopped}.NotifyStopped', e(names.CLEANED))

    def _entry_actions(self, state: str) -> None:
        """Raise the events of ``state`` (Fig. 5): -ing states act on this composite, then on its
        children; -ed states notify the parent."""
        leaf = state.rsplit('.', 1)[-1]
        if self._self_driven:
            self._drive_self(state, leaf)
        if state.startswith('Active.Run.Running.'):  # a state of the application's sub-FSM
            for s in self._running.states if self._running is not None else ():
                if s.name == leaf:
                    for name in s.raise_on_entry:
                        self._raise(name, False)
            return
        for target, suffix in _ENTRY_EVENTS.get(leaf, ()):
            if target == 'own':
                self._raise(self.event(suffix), False)
            elif target == 'children':
                for child in self.children:
                    if suffix == names.CONFIGURE:  # from now on it has something to stop
                        self._stopping.requires = self._stopping.requires | {self.event(names.STOPPED, child)}
                    self._raise(self.event(suffix, child), False)
            else:
                self._raise(self.event(suffix), True)
        if state == 'Safety':
            for name in self._safety_to_parent:
                self._raise(name, True)

    def _drive_self(self, state: str, leaf: str) -> None:
        """A composite recovering on its own commands itself what its parent would (start, run),
        once it notified the parent of the -ed state; it stops doing so in Running, Stop or Safety."""
        if leaf == 'NotifyConfigured':
            self._memory.add(self.event(names.START))
        elif leaf == 'Started':
            self._memory.add(self.event(names.RUN))
        elif leaf == 'Running' or state == 'Safety' or state.startswith('Active.Stop'):
            self._self_driven = False

    def waiting_for(self) -> list[str]:
        """The events the current state still waits for (those of its first transition out that
        needs any), e.g. ``['e_track_configured']``."""
        for t in self._transitions:
            if t.requires and self.state.startswith(t.source) and t.source != 'Active':
                missing = sorted(t.requires - self._memory)
                if missing:
                    return missing
        return []

    @property
    def starting_up(self) -> bool:
        """In a state on the way to Running that waits for this composite's own entities or its
        children (not for a command of its parent, which may be waiting for a slower sibling)."""
        return self.state.rsplit('.', 1)[-1] in _STARTUP_WAITS

    @property
    def running_substate(self) -> str | None:
        prefix = 'Active.Run.Running.'
        return self.state[len(prefix):] if self.state.startswith(prefix) else None

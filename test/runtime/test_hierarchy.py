"""The Composition Pattern runtime with real rclpy nodes over real DDS (issue: runtime tests 1-4,
6, 7): life-cycle order, Scheduler order, Stop, Safety, semantic checks, run-time composition."""

from __future__ import annotations

import gc

import pytest

import test_support_probes as probes
from hierarchy_harness import Hierarchy
from itasc_core.coordination.coordinator import Coordinator

PROBE = 'test_support_probes:OrderProbe'


def task(name: str, **probe_params) -> dict:
    return {
        'name': name,
        'entities': [
            {'name': 'first', 'kind': PROBE, 'parameters': probe_params},
            {'name': 'second', 'kind': PROBE},
        ],
    }


def model(**program_extra) -> dict:
    """root { program { T1 { 2 FEs }, T2 { 2 FEs }, 1 FE }, 1 FE }: three levels."""
    program = {'name': 'program', 'entities': [task('T1'), task('T2'), {'name': 'mix', 'kind': PROBE}]}
    program.update(program_extra)
    return {'name': 'root', 'rate': 200, 'entities': [program, {'name': 'plant', 'kind': PROBE}]}


CONFIGURE_TO_RUNNING = [
    'Active.Configure.Configuring.DeployEntities',
    'Active.Configure.Configuring.ConfigureEntities',
    'Active.Configure.Configured.ConnectEntities',
    'Active.Configure.Configured.NotifyConfigured',
    'Active.Start.Starting',
    'Active.Start.Started',
    'Active.Run.PreRunning',
    'Active.Run.Running',
]
STOP = [
    'Active.Stop.Stopping',
    'Active.Stop.Stopped.Disengage',
    'Active.Stop.Stopped.CleanupComputation',
    'Active.Stop.Stopped.Cleanup',
    'Active.Stop.Stopped.NotifyStopped',
]
COMPOSITES = ('root', 'program', 'T1', 'T2')


@pytest.fixture
def hierarchy(request):
    h = Hierarchy(getattr(request, 'param', None) or model())
    yield h
    h.close()


def all_running(h: Hierarchy) -> bool:
    return all(h.coordinators.get(c) is not None and h.state(c).startswith('Active.Run.Running')
               for c in COMPOSITES)


def first_time(h: Hierarchy, composite: str, state: str) -> float:
    return next(t for t, s in h.stamps[composite] if s == state)


def test_hierarchy_reaches_running_in_the_papers_order(hierarchy):
    hierarchy.start()
    assert hierarchy.spin_until(lambda: all_running(hierarchy)), {c: hierarchy.state(c) for c in hierarchy.coordinators}
    for composite in COMPOSITES:
        assert hierarchy.states(composite) == CONFIGURE_TO_RUNNING, composite
    # -ed states of a parent only after every child reported (∀ in Fig. 5).
    for parent, children in {'root': ['program'], 'program': ['T1', 'T2']}.items():
        for parent_state, child_state in [
            ('Active.Configure.Configured.ConnectEntities', 'Active.Configure.Configured.NotifyConfigured'),
            ('Active.Start.Started', 'Active.Start.Started'),
            ('Active.Run.Running', 'Active.Run.Running'),
        ]:
            for child in children:
                assert first_time(hierarchy, parent, parent_state) >= first_time(hierarchy, child, child_state)


def test_scheduler_runs_entities_in_declared_order_children_in_the_same_tick(hierarchy):
    hierarchy.start()
    assert hierarchy.spin_until(lambda: all_running(hierarchy))
    probes.CALLS.clear()
    expected = ['/root/program/T1/first', '/root/program/T1/second', '/root/program/T2/first',
                '/root/program/T2/second', '/root/program/mix', '/root/plant']

    def by_tick() -> dict[float, list[str]]:
        ticks: dict[float, list[str]] = {}
        for t, name in list(probes.CALLS):
            ticks.setdefault(t, []).append(name)
        return ticks

    assert hierarchy.spin_until(lambda: len(by_tick()) >= 22, timeout=10), 'fewer than 22 ticks in 10 s'
    ticks = by_tick()
    complete = [names for names in ticks.values() if len(names) == len(expected)]
    assert len(complete) >= 20, f'only {len(complete)} complete ticks of {len(ticks)}'
    assert all(names == expected for names in complete)
    assert all(len(names) == len(expected) for names in list(ticks.values())[1:-1])


def test_a_full_collection_while_running_walks_only_what_was_made_since_the_bring_up(hierarchy):
    """The cyclic garbage collector's full collection walks every object it tracks and holds the
    interpreter meanwhile: with what an application's bring-up builds, ~60 ms without a tick. Once
    the Schedulers run, what exists is left out of collections."""
    gc.unfreeze()  # what earlier tests of this process left frozen: count from a plain start
    tracked = len(gc.get_objects())
    hierarchy.start()
    assert hierarchy.spin_until(lambda: all_running(hierarchy))
    hierarchy.spin_for(0.5)
    walked = len(gc.get_objects())  # what a full collection would walk now
    assert walked < tracked / 10, f'a full collection walks {walked} objects of the {tracked} tracked before'


def test_stop_goes_through_stopping_and_the_four_stopped_substates(hierarchy):
    hierarchy.start()
    assert hierarchy.spin_until(lambda: all_running(hierarchy))
    assert len(hierarchy.executor.get_nodes()) > 20
    hierarchy.raise_event('e_root_stop')
    assert hierarchy.spin_until(lambda: hierarchy.state('root').endswith('NotifyStopped'))
    for composite in COMPOSITES:
        assert hierarchy.states(composite)[len(CONFIGURE_TO_RUNNING):] == STOP, composite
    hierarchy.spin_for(0.1)
    remaining = [n.get_fully_qualified_name() for n in hierarchy.executor.get_nodes()]
    # Only the root's Coordinator, Composer and Configurator remain, for the bootstrap to destroy,
    # and the process's event hub and writers (named after the root)
    assert sorted(remaining) == ['/root', '/root/_event_hub', '/root/composer', '/root/configurator',
                                 '/root/coordinator', '/root/test_driver']


@pytest.mark.parametrize('hierarchy', [model(safety={'raise_to_parent': ['e_program_fault']})], indirect=True)
def test_emergency_puts_the_raising_composite_in_safety_and_needs_reconfiguration(hierarchy):
    hierarchy.listen('/root')
    hierarchy.start()
    assert hierarchy.spin_until(lambda: all_running(hierarchy))
    # An entity of the program composite raises e_emergency while Running.
    hierarchy.raise_event('e_emergency', '/root/program')
    assert hierarchy.spin_until(lambda: hierarchy.state('program') == 'Safety', timeout=2)
    assert hierarchy.state('root').startswith('Active.Run.Running')  # the application decides
    assert hierarchy.spin_until(lambda: any(e.name == 'e_program_fault' for e in hierarchy.events), timeout=2)
    # Safety is left only by reconfiguration: run/start are ignored.
    hierarchy.raise_event('e_program_run', '/root')
    hierarchy.raise_event('e_program_start', '/root')
    hierarchy.spin_for(0.2)
    assert hierarchy.state('program') == 'Safety'
    hierarchy.raise_event('e_program_configure', '/root')
    assert hierarchy.spin_until(lambda: hierarchy.state('program') == 'Active.Configure.Configured.NotifyConfigured')


@pytest.mark.parametrize('state', ['Active.Configure.Configured.NotifyConfigured', 'Active.Start.Started'])
def test_emergency_in_other_states_of_active(state, monkeypatch):
    """An emergency raised while T1 is in ``state`` puts it in Safety. It is raised as T1 enters the
    state: T1 can pass through NotifyConfigured within one spin (when it is the last Task to be
    configured, the program commands Start in the same spin), too fast for the test to see it."""
    entered = Coordinator._publish_state

    def publish_state(self, new: str, previous: str, event: str) -> None:
        entered(self, new, previous, event)
        if self.composite.name == 'T1' and new == state:
            self.raise_event('e_emergency')  # on T1's event topic, as the test would

    monkeypatch.setattr(Coordinator, '_publish_state', publish_state)
    h = Hierarchy(model())
    try:
        h.start()
        assert h.spin_until(lambda: h.coordinators.get('T1') is not None and h.state('T1') == 'Safety')
        states = [s for s, *_ in h.coordinators['T1'].history]
        assert states[states.index(state) + 1] == 'Safety', states
    finally:
        h.close()


def test_emergency_raised_by_a_functional_entity_at_the_deepest_level():
    program = model()
    program['entities'][0]['entities'][0] = task('T1', raise_on_tick='e_emergency', at_tick=5)
    h = Hierarchy(program)
    try:
        h.start()
        assert h.spin_until(lambda: h.coordinators.get('T1') is not None and h.state('T1') == 'Safety')
        assert h.spin_until(lambda: h.state('T2').startswith('Active.Run.Running'), timeout=2)  # T2 unaffected
        scheduler = h.composer.children['program'].children['T1'].scheduler
        assert h.spin_until(lambda: not scheduler.active, timeout=1)  # e_T1_safety reached it
        ticks = scheduler.ticks
        h.spin_for(0.2)
        assert scheduler.ticks == ticks  # nothing computes in Safety
    finally:
        h.close()


def test_connection_with_disagreeing_semantics_is_refused_naming_both_ports():
    bad = {'name': 'root', 'rate': 100, 'entities': [
        {'name': 'source', 'kind': 'SineSource', 'parameters': {'semantics': 'Position(ee|base)'}},
        {'name': 'ctrl', 'kind': 'PController', 'parameters': {'semantics': 'Position(ee|world)'}},
    ], 'connections': [{'from': 'source.signal', 'to': 'ctrl.setpoint'}]}
    h = Hierarchy(bad)
    try:
        h.listen('/root')
        h.start()
        assert h.spin_until(lambda: any(e.name == 'e_root_connection_refused' for e in h.events))
        refusal = next(e for e in h.events if e.name == 'e_root_connection_refused')
        assert '/root/source.signal' in refusal.detail and '/root/ctrl.setpoint' in refusal.detail
        assert "'Position(ee|base)' != 'Position(ee|world)'" in refusal.detail
        assert h.spin_until(lambda: h.state('root') == 'Safety', timeout=2)
        assert not h.composer.entities['ctrl'].inputs['setpoint'].connected
    finally:
        h.close()


def test_task_added_while_running_reaches_running_and_others_never_leave_it():
    steps = {'add_T3': {'add': [task('T3')], 'connections': []}}
    h = Hierarchy(model(composition_steps=steps))
    try:
        h.start()
        assert h.spin_until(lambda: all_running(h))
        before = {c: len(h.states(c)) for c in COMPOSITES}
        probes.CALLS.clear()
        h.raise_event('e_program_compose_add_T3', '/root/program')
        assert h.spin_until(lambda: 'T3' in h.coordinators and h.state('T3') == 'Active.Run.Running')
        assert h.states('T3') == CONFIGURE_TO_RUNNING
        h.spin_for(0.2)
        assert {c: len(h.states(c)) for c in COMPOSITES} == before  # nobody else moved
        assert any(name == '/root/program/T3/first' for _, name in probes.CALLS)  # and it computes
        h.raise_event('e_root_stop')
        assert h.spin_until(lambda: h.state('root').endswith('NotifyStopped'))
        assert h.states('T3')[-1] == 'Active.Stop.Stopped.NotifyStopped'
    finally:
        h.close()


def test_inactive_entities_compute_nothing_until_activated():
    h = Hierarchy(model(inactive=['T2']))
    try:
        h.start()
        assert h.spin_until(lambda: all_running(h))
        probes.CALLS.clear()
        ticks = lambda: {t for t, _ in list(probes.CALLS)}  # noqa: E731
        assert h.spin_until(lambda: len(ticks()) >= 10, timeout=10)
        assert not any('/T2/' in name for _, name in probes.CALLS)
        h.raise_event('e_T2_activate', '/root/program')
        assert h.spin_until(lambda: any('/T2/' in name for _, name in list(probes.CALLS)), timeout=10)
    finally:
        h.close()


def test_an_entity_switched_on_again_is_told_so_once():
    h = Hierarchy(model(inactive=['T2']))
    try:
        h.start()
        assert h.spin_until(lambda: all_running(h))
        first = h.composer.children['program'].children['T2'].entities['first']
        assert first.activations == 0
        h.raise_event('e_T2_activate', '/root/program')
        assert h.spin_until(lambda: first.activations == 1, timeout=2)
        h.raise_event('e_T2_activate', '/root/program')  # already on: nothing to restart
        h.spin_for(0.1)
        assert first.activations == 1
    finally:
        h.close()


def test_the_entities_of_a_composite_switched_off_are_told_so_once():
    """``e_T1_deactivate``: every entity of T1 hears that it is off (a Task's rows leave the Solver's
    problem at once), then T1 computes nothing; said again, nobody hears it twice."""
    h = Hierarchy(model())
    try:
        h.start()
        assert h.spin_until(lambda: all_running(h))
        t1 = h.composer.children['program'].children['T1'].entities
        h.raise_event('e_T1_deactivate', '/root/program')
        assert h.spin_until(lambda: all(e.deactivations == 1 for e in t1.values()), timeout=2)
        probes.CALLS.clear()
        h.raise_event('e_T1_deactivate', '/root/program')  # already off
        h.spin_for(0.2)
        assert [e.deactivations for e in t1.values()] == [1, 1]
        assert probes.CALLS and not any('/T1/' in name for _, name in probes.CALLS)
    finally:
        h.close()


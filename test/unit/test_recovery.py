"""Leaving Safety the paper's way (§6.1: by reconfiguration), piece by piece: the life-cycle FSM
reconfigures and restarts a composite (on its own when its parent runs on), the fault check
tells a cause that is still there from one that is gone, and a watchdog Monitor answers whether
its condition still holds on the data that came since."""

from __future__ import annotations

import math

import pytest
import rclpy

from itasc_core.coordination.lifecycle import LifecycleFsm, RunningFsmSpec, RunningState, RunningTransition
from itasc_core.coordination.recovery import CHECK_TIMEOUT, COMPOSER, FaultCheck, Faults

RUNNING = RunningFsmSpec(initial='approach', states=(RunningState('approach'), RunningState('hold')),
                         transitions=(RunningTransition('approach', 'hold', ('e_arrived',)),))


class Recorder:
    def __init__(self, **kwargs) -> None:
        self.raised: list[tuple[str, bool]] = []
        self.fsm = LifecycleFsm(raise_event=lambda n, up: self.raised.append((n, up)), **kwargs)

    def feed(self, *events: str) -> None:
        for event in events:
            self.fsm.process(event)


def to_safety(r: Recorder, c: str, children=()) -> None:
    r.feed(f'e_{c}_configure', f'e_{c}_deployed', f'e_{c}_entities_configured',
           *(f'e_{k}_configured' for k in children), f'e_{c}_connected', f'e_{c}_start',
           f'e_{c}_scheduler_initialized', *(f'e_{k}_started' for k in children), f'e_{c}_run',
           f'e_{c}_scheduler_activated', *(f'e_{k}_running' for k in children), 'e_arrived', 'e_emergency')
    assert r.fsm.state == 'Safety'


def test_a_composite_whose_parent_runs_on_recovers_by_itself_through_configure_start_and_run():
    r = Recorder(composite='task', running=RUNNING)
    to_safety(r, 'task')
    assert r.fsm.recover()
    r.feed('e_task_deployed', 'e_task_entities_configured', 'e_task_connected')
    assert r.fsm.state == 'Active.Start.Starting'  # no e_task_start from the parent needed
    r.feed('e_task_scheduler_initialized')
    assert r.fsm.state == 'Active.Run.PreRunning'  # nor e_task_run
    r.feed('e_task_scheduler_activated')
    assert r.fsm.state == 'Active.Run.Running.approach'  # the Running sub-FSM starts over
    notified = [name for name, up in r.raised if up]
    assert notified[-3:] == ['e_task_configured', 'e_task_started', 'e_task_running'], notified
    # once Running, it waits for its parent's commands again: a later reconfiguration by the parent
    # is driven by the parent
    r.feed('e_emergency', 'e_task_configure', 'e_task_deployed', 'e_task_entities_configured', 'e_task_connected')
    assert r.fsm.state == 'Active.Configure.Configured.NotifyConfigured'


def test_the_root_recovers_with_its_children_reconfigured():
    r = Recorder(composite='app', is_root=True, children=['program'])
    to_safety(r, 'app', children=['program'])
    assert ('e_program_emergency', False) in r.raised
    assert r.fsm.recover()
    r.feed('e_app_deployed', 'e_app_entities_configured')
    assert ('e_program_configure', False) in r.raised[-3:]  # the children are reconfigured too
    r.feed('e_program_configured', 'e_app_connected', 'e_app_scheduler_initialized', 'e_program_started',
           'e_app_scheduler_activated', 'e_program_running')
    assert r.fsm.state == 'Active.Run.Running'


def test_recover_outside_safety_does_nothing():
    r = Recorder(composite='app', is_root=True)
    assert not r.fsm.recover()
    assert r.fsm.state == 'Init'


def test_the_faults_own_entities_raised_are_asked_and_a_check_ends_on_the_first_cause_still_there():
    faults = Faults('/app/program')
    faults.add('e_emergency', '/app/program/Solver', 'infeasible')
    faults.add('e_emergency', '/app/program/track/coordinator', '')  # a child: asked as a child
    faults.add('e_program_emergency', '/app/coordinator', '')  # the parent: not ours to ask
    assert faults.own_sources() == ['/app/program/Solver']

    check = FaultCheck(1, {COMPOSER, 'track'}, started=0.0)
    check.answer('track', '')
    assert not check.done(0.1)
    check.answer(COMPOSER, 'Driver_silent: stale')
    assert check.done(0.1) and check.outcome(0.1) == 'Driver_silent: stale'

    silent = FaultCheck(2, {COMPOSER, 'track'}, started=0.0)
    silent.answer(COMPOSER, '')
    assert not silent.done(CHECK_TIMEOUT - 0.1)
    assert silent.done(CHECK_TIMEOUT + 0.1) and 'track' in silent.outcome(CHECK_TIMEOUT + 0.1)


# -- a watchdog Monitor asked whether its condition still holds ------------------------------------------

@pytest.fixture
def ros():
    rclpy.init()
    yield
    rclpy.try_shutdown()


def _monitor(condition: str, **parameters):
    from sensor_msgs.msg import JointState
    from itasc_core.communication.ports import PortSpec
    from itasc_core.computation.monitor import Monitor
    from itasc_core.entity import CompositeContext

    watch = PortSpec(name='joint_state', direction='output', msg_type=JointState, type='joint_state',
                     semantics='JointPositions(arm)', id='/app/Driver/joint_state')
    return Monitor('watchdog', composite=CompositeContext(name='app', namespace='/app'), watch=watch,
                   parameters={'condition': condition, 'event': 'e_emergency', **parameters})


def test_a_stale_watchdog_says_so_until_data_comes_again(ros, monkeypatch):
    from sensor_msgs.msg import JointState
    from itasc_core.computation import monitor as monitor_module

    watchdog = _monitor('stale', timeout=0.25)
    now = [100.0]
    monkeypatch.setattr(monitor_module.time, 'monotonic', lambda: now[0])
    try:
        assert 'nothing ever came' in watchdog.fault_persists()
        watchdog.watch.received_at = 99.9  # a sample 0.1 s ago
        watchdog.watch.latest = JointState(name=['a'], position=[0.0])
        assert watchdog.fault_persists() is None
        now[0] = 103.0  # silent for 3.1 s
        assert 'stale' in watchdog.fault_persists() and '3.1 s' in watchdog.fault_persists()
    finally:
        watchdog.destroy_node()


def test_a_non_finite_watchdog_says_so_while_a_nan_still_comes_in(ros):
    from sensor_msgs.msg import JointState

    watchdog = _monitor('nonfinite', field='position')
    try:
        assert watchdog.fault_persists() is None  # no data yet: nothing to say
        watchdog.watch.deliver(JointState(name=['a', 'b'], position=[0.1, math.nan]), '/app/Driver/joint_state')
        assert 'nonfinite' in watchdog.fault_persists()
        watchdog.watch.deliver(JointState(name=['a', 'b'], position=[0.1, 0.2]), '/app/Driver/joint_state')
        assert watchdog.fault_persists() is None
    finally:
        watchdog.destroy_node()

"""The life-cycle FSM as a plain event processor (paper §6.1, Figs. 4-6), no ROS involved."""

from __future__ import annotations

import pytest

from itasc_core.coordination.lifecycle import LifecycleFsm, RunningFsmSpec, RunningState, RunningTransition


class Recorder:
    def __init__(self, **kwargs) -> None:
        self.raised: list[tuple[str, bool]] = []
        self.states: list[str] = []
        self.fsm = LifecycleFsm(raise_event=lambda n, up: self.raised.append((n, up)),
                                on_state=lambda s, _p, _e: self.states.append(s), **kwargs)

    def feed(self, *events: str) -> None:
        for event in events:
            self.fsm.process(event)


def bring_to_running(r: Recorder, c: str = 'itasc', children=('A', 'B')) -> None:
    r.feed(f'e_{c}_configure', f'e_{c}_deployed', f'e_{c}_entities_configured',
           *(f'e_{k}_configured' for k in children), f'e_{c}_connected', f'e_{c}_start',
           f'e_{c}_scheduler_initialized', *(f'e_{k}_started' for k in children), f'e_{c}_run',
           f'e_{c}_scheduler_activated', *(f'e_{k}_running' for k in children))


def test_waits_for_all_children_in_any_order_event_memory():
    r = Recorder(composite='itasc', children=['A', 'B'])
    r.feed('e_itasc_configure', 'e_itasc_deployed', 'e_B_configured')
    assert r.fsm.state == 'Active.Configure.Configuring.ConfigureEntities'
    r.feed('e_itasc_entities_configured')
    assert r.fsm.state == 'Active.Configure.Configuring.ConfigureEntities'  # A still missing
    r.feed('e_A_configured')
    assert r.fsm.state == 'Active.Configure.Configured.ConnectEntities'


def test_event_memory_is_cleared_on_state_entry():
    r = Recorder(composite='itasc', children=['A'])
    # e_A_configured arriving before ConfigureEntities was entered does not count.
    r.feed('e_itasc_configure', 'e_A_configured', 'e_itasc_deployed', 'e_itasc_entities_configured')
    assert r.fsm.state == 'Active.Configure.Configuring.ConfigureEntities'
    r.feed('e_A_configured')
    assert r.fsm.state == 'Active.Configure.Configured.ConnectEntities'


def test_ing_states_command_own_entities_before_children_and_ed_states_notify_parent():
    r = Recorder(composite='itasc', children=['A'])
    r.feed('e_itasc_configure', 'e_itasc_deployed')
    assert r.raised[-2:] == [('e_itasc_configure_entities', False), ('e_A_configure', False)]
    r.feed('e_itasc_entities_configured', 'e_A_configured', 'e_itasc_connected')
    assert r.raised[-1] == ('e_itasc_configured', True)


def test_root_moves_from_ed_to_ing_on_its_own():
    r = Recorder(composite='app', is_root=True)
    r.feed('e_app_configure', 'e_app_deployed', 'e_app_entities_configured', 'e_app_connected')
    assert r.fsm.state == 'Active.Start.Starting'
    r.feed('e_app_scheduler_initialized')
    assert r.fsm.state == 'Active.Run.PreRunning'


def test_running_sub_fsm_from_data():
    spec = RunningFsmSpec(initial='approach',
                          states=(RunningState('approach', ('e_ApproachObject_activate',)),
                                  RunningState('grasp', ('e_high_accuracy_control',)), RunningState('retreat')),
                          transitions=(RunningTransition('approach', 'grasp', ('e_near', 'e_slow')),
                                       RunningTransition('grasp', 'retreat', ('e_grasped',))))
    r = Recorder(composite='itasc', children=['A', 'B'], running=spec)
    bring_to_running(r)
    assert r.fsm.state == 'Active.Run.Running.approach'
    assert ('e_ApproachObject_activate', False) in r.raised
    r.feed('e_near')
    assert r.fsm.state == 'Active.Run.Running.approach'  # needs both events
    r.feed('e_slow')
    assert r.fsm.state == 'Active.Run.Running.grasp'
    assert r.raised[-1] == ('e_high_accuracy_control', False)
    r.feed('e_grasped')
    assert r.fsm.running_substate == 'retreat'


@pytest.mark.parametrize('events', [
    ['e_itasc_configure'],
    ['e_itasc_configure', 'e_itasc_deployed'],
    ['e_itasc_configure', 'e_itasc_deployed', 'e_itasc_entities_configured', 'e_A_configured', 'e_itasc_connected'],
])
def test_safety_from_any_state_of_active_and_only_reconfiguration_leaves_it(events):
    r = Recorder(composite='itasc', children=['A'], safety_to_parent=['e_itasc_failed'])
    r.feed(*events, 'e_emergency')
    assert r.fsm.state == 'Safety'
    assert ('e_itasc_safety', False) in r.raised and ('e_itasc_failed', True) in r.raised
    r.feed('e_itasc_start', 'e_itasc_run', 'e_itasc_deployed')
    assert r.fsm.state == 'Safety'
    r.feed('e_itasc_configure')
    assert r.fsm.state == 'Active.Configure.Configuring.DeployEntities'


def test_failed_composition_step_leads_to_safety():
    r = Recorder(composite='itasc')
    r.feed('e_itasc_configure', 'e_itasc_deploy_failed')
    assert r.fsm.state == 'Safety'


def test_stop_order_and_adopted_children_are_waited_for():
    r = Recorder(composite='itasc', children=['A'])
    bring_to_running(r, children=['A'])
    r.fsm.adopt('T3')
    assert r.raised[-1] == ('e_T3_configure', False)
    r.feed('e_T3_configured')
    assert r.raised[-1] == ('e_T3_start', False)
    r.feed('e_T3_started')
    assert r.raised[-1] == ('e_T3_run', False)
    r.feed('e_itasc_stop', 'e_A_stopped')
    assert r.fsm.state == 'Active.Stop.Stopping'  # T3 not stopped yet
    r.feed('e_T3_stopped', 'e_itasc_disengaged', 'e_itasc_computation_cleaned', 'e_itasc_cleaned')
    assert r.states[-5:] == ['Active.Stop.Stopping', 'Active.Stop.Stopped.Disengage',
                             'Active.Stop.Stopped.CleanupComputation', 'Active.Stop.Stopped.Cleanup',
                             'Active.Stop.Stopped.NotifyStopped']
    assert r.raised[-1] == ('e_itasc_stopped', True)


def test_a_released_child_is_commanded_to_stop_and_no_longer_waited_for():
    r = Recorder(composite='itasc', children=['A', 'B'])
    bring_to_running(r, children=['A', 'B'])
    r.fsm.release('B')
    assert r.raised[-1] == ('e_B_stop', False) and r.fsm.children == ('A',)
    r.feed('e_itasc_stop', 'e_A_stopped')  # B is not waited for
    assert r.fsm.state == 'Active.Stop.Stopped.Disengage'
    assert ('e_B_stop', False) not in r.raised[r.raised.index(('e_B_stop', False)) + 1:]

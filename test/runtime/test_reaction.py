"""How soon a running application acts on a Monitor (issue #9, paper Fig. 3 and §6.2): the Timer's
tick is followed by the Coordinators' turn in this process, so the configuration switch that the
Running sub-FSM commands on a Monitor's event reaches the Task's Constraint Controller before the
next tick, which computes with the new gains (a reaction of two ticks, counting the Driver acting
on that tick's command)."""

from __future__ import annotations

from hierarchy_harness import Hierarchy


def test_a_monitors_event_in_one_tick_changes_the_task_gains_before_the_next():
    from itasc_bringup.apps import load_composition

    # at 1 kHz: a Coordinator's own update (200 Hz) is five ticks apart
    h = Hierarchy(load_composition('approach_object').model_copy(update={'rate': 1000.0}))
    try:
        h.start()
        assert h.spin_until(lambda: h.coordinators.get('ApproachObject') is not None
                            and h.state('itasc').startswith('Active.Run.Running'), timeout=60)
        ticks = h.composer.scheduler
        program = h.composer.children['itasc']
        cc = program.children['ApproachObject'].entities['CC']
        monitor = program.monitors['tracking_error']
        raised_in: list[int] = []
        changed_after: list[int] = []  # the last tick computed with the old gains
        raise_event, configure = monitor.raise_event, cc.configure
        gains = cc.controller.kp

        def raising(*args, **kwargs):
            raised_in.append(ticks.ticks)
            return raise_event(*args, **kwargs)

        def configuring(params) -> None:
            configure(params)
            if cc.controller.kp != gains and not changed_after:
                changed_after.append(ticks.ticks)
        monitor.raise_event, cc.configure = raising, configuring
        assert h.spin_until(lambda: bool(changed_after), timeout=60), f'no new gains (Monitor raised in {raised_in})'
        assert raised_in and changed_after == [raised_in[0]], (raised_in, changed_after)
    finally:
        h.close()

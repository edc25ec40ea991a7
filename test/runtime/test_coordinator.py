"""The Coordinator between ticks (:mod:`itasc_core.coordination.coordinator`): it updates when there
is something to update, and a start-up state still times out on time after it slept."""

from __future__ import annotations

import functools
import time

import rclpy
from rclpy.signals import SignalHandlerOptions

from itasc_core.communication.event_names import CONFIGURE, TIMEOUT, event
from itasc_core.communication.events import EventListener, EventRaiser
from itasc_core.composition.deployment import make_executor
from itasc_core.coordination.coordinator import Coordinator
from itasc_core.entity import CompositeContext
from ros_teardown import destroy_all


def _spin(executor, seconds: float, until=lambda: False) -> None:
    """Spin ``executor`` for ``seconds``, or until ``until()``."""
    end = time.monotonic() + seconds
    while time.monotonic() < end and not until():
        executor.spin_once(timeout_sec=0.01)


class CountingCoordinator(Coordinator):
    """A Coordinator that counts its updates."""

    updates = 0

    def update(self) -> None:
        self.updates += 1
        super().update()


def test_an_idle_coordinator_sleeps_and_a_start_up_state_entered_after_its_sleep_times_out_on_time():
    """Before, every Coordinator was updated 200 times a second, for nothing while no event came:
    each composite's process woke 250 times a second. Asleep, it must still hear its events at
    once, and measure a start-up state's wait from when it was entered, not from its last update
    (a longer gap between two updates is taken for time spent elsewhere, and not counted)."""
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    executor = make_executor()
    try:
        composite = CompositeContext(name='lone', namespace='/lone')
        coordinator = CountingCoordinator(composite=composite, startup_timeout=1.0)
        driver = rclpy.create_node('driver', namespace='/lone')
        heard: list[tuple[str, float]] = []
        EventListener(driver, topics=[composite.events_topic], immediate=True,
                      on_priority=lambda msg: heard.append((msg.name, time.monotonic())))
        raiser = EventRaiser(driver, topic=composite.events_topic)
        executor.add_node(coordinator)
        executor.add_node(driver)

        spin = functools.partial(_spin, executor)
        spin(10.0, until=lambda: raiser.publisher.get_subscription_count() > 0)
        spin(0.3)  # the updates of the start, if any
        before = coordinator.updates
        spin(1.5)
        assert coordinator.updates - before <= 1, coordinator.updates - before  # was ~300

        raiser.raise_event(event('lone', CONFIGURE))
        spin(5.0, until=lambda: coordinator.state.endswith('DeployEntities'))
        assert coordinator.state.endswith('DeployEntities'), coordinator.history
        entered = coordinator.history[-1][2]
        # nobody deploys anything: the state times out after startup_timeout
        spin(5.0, until=lambda: any(name == event('lone', TIMEOUT) for name, _ in heard))
        timed_out = [at for name, at in heard if name == event('lone', TIMEOUT)]
        assert timed_out, coordinator.history
        assert 1.0 <= timed_out[0] - entered < 1.5, timed_out[0] - entered  # not 1 s + the 1.5 s asleep
        assert coordinator.state.startswith('Safety'), coordinator.state
    finally:
        destroy_all(executor)


def test_a_composites_life_cycle_commands_count_from_its_parent_only():
    """``e_<c>_stop`` published on a program composite's own event topic (``ros2 topic pub``) stopped
    the program behind the root's back: the root went on reporting Running, and its own stop later
    waited 20 s for a stop that had gone by (exit 1). A composite's life-cycle commands are its
    parent's to give, on the parent's topic; on its own topic they are ignored."""
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    executor = make_executor()
    try:
        parent = CompositeContext(name='app', namespace='/app')
        child = parent.child('program')
        coordinator = Coordinator(composite=child)
        operator = rclpy.create_node('operator', namespace='/app')
        own, from_parent = (EventRaiser(operator, topic=topic) for topic in (child.events_topic, parent.events_topic))
        executor.add_node(coordinator)
        executor.add_node(operator)

        spin = functools.partial(_spin, executor)
        spin(10.0, until=lambda: own.publisher.get_subscription_count() > 0
             and from_parent.publisher.get_subscription_count() > 0)
        own.raise_event(event('program', CONFIGURE))
        spin(1.0)
        assert coordinator.state == 'Init', coordinator.history
        from_parent.raise_event(event('program', CONFIGURE))
        spin(5.0, until=lambda: coordinator.state.endswith('DeployEntities'))
        assert coordinator.state.endswith('DeployEntities'), coordinator.history
    finally:
        destroy_all(executor)
        rclpy.try_shutdown()

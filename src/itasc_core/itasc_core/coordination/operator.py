"""Operating a running composite from ROS (paper §6.1 life-cycle FSM, Safety and its recovery by
reconfiguration; §7.2 events): the operator services every composite's Coordinator offers.

``<composite namespace>/coordinator/``:

* ``raise_event`` (``itasc_msgs/srv/RaiseEvent``) puts an event from source ``operator`` on the
  composite's event topic: an event of the Running sub-FSM (``e_object_grasped``), or
  ``e_emergency``. Refused, with the reason, for a name no state of the Coordinator reacts to,
  and for the life-cycle's own commands and notifications (``recover`` and ``stop`` are the ways
  to change the life-cycle).
* ``recover`` (``std_srvs/srv/Trigger``) leaves Safety the paper's way: reconfigure, restart,
  Running. Refused when the composite is not in Safety, when its parent is in Safety (recover the
  parent: it reconfigures its children), or when a cause is still there (:mod:`.recovery` says
  how that is asked). Accepted, it raises ``e_<c>_recovering`` (detail: the faults it leaves
  behind) and reconfigures; it answers once the composite is Running again, or failed on the way.
* ``stop`` (``std_srvs/srv/Trigger``) asks for the orderly stop of the whole hierarchy: the
  request (``e_stop_requested``) travels up from Coordinator to parent Coordinator to the root's
  event topic, where the bootstrap stops the application as it does on SIGINT.

The Coordinator stays a pure event processor: the services only raise events and look at its FSM;
everything they start travels as events.
"""

from __future__ import annotations

import time
from typing import Callable

from std_srvs.srv import Trigger

from itasc_msgs.srv import RaiseEvent

from ..communication.deferred_service import Later, create_deferred_service
from ..communication.event_names import SAFETY_EVENT
from ..communication.events import EventRaiser
from ..entity import CompositeContext
from .lifecycle import LifecycleFsm
from .recovery import (COMPOSER, FaultCheck, Faults, check_answer, check_request, is_fault, parse_answer,
                       parse_request)

__all__ = ['Operator', 'OPERATOR', 'STOP_REQUESTED']

#: The source of the events an operator raises.
OPERATOR = 'operator'
#: Asks the root's owner (the bootstrap) to stop the application in order; detail: who asked.
STOP_REQUESTED = 'e_stop_requested'


class Operator:
    """The operator services of one Coordinator, and the fault checks before a recovery."""

    def __init__(self, node, *, composite: CompositeContext, fsm: LifecycleFsm, raise_own: Callable[..., None],
                 to_parent: EventRaiser | None) -> None:
        """``raise_own(name, detail=...)`` raises as the Coordinator on its composite's topic;
        ``to_parent`` on the parent's (None for the root)."""
        self._node = node
        self._composite = composite
        self._name = composite.name
        self._fsm = fsm
        self._raise_own = raise_own
        self._to_parent = to_parent
        self._operator = EventRaiser(node, topic=composite.events_topic, source=OPERATOR)
        self.faults = Faults(composite.namespace)
        #: The parent is in Safety (it commanded ``e_<c>_emergency``, or was told by this composite).
        self.parent_in_safety = False
        self._number = 0
        self._check: FaultCheck | None = None
        self._then: list[Callable[[str], None]] = []
        self._awaiting_running: list[Later] = []
        node.create_service(RaiseEvent, '~/raise_event', self._raise_event)
        create_deferred_service(node, Trigger, '~/recover', self._recover)
        node.create_service(Trigger, '~/stop', self._stop)

    # -- the services ---------------------------------------------------------------------------------

    def _raise_event(self, request, response):
        name = request.name.strip()
        allowed = self._fsm.running_events() | {SAFETY_EVENT}
        if not self._fsm.is_relevant(name):
            reacts = ', '.join(sorted(allowed))
            return _answer(response, False, f"no state of {self._name}'s Coordinator reacts to '{name}'"
                                            f' (it reacts to: {reacts})')
        if name not in allowed:
            return _answer(response, False, f"'{name}' belongs to the life-cycle of {self._name}: use "
                                            '~/recover or ~/stop')
        reacts_now = self._fsm.reacts_now(name)
        self._operator.raise_event(name, detail=request.detail)
        note = '' if reacts_now else f' (its current state {self._fsm.state} does not react to it)'
        return _answer(response, True, f'raised {name} on {self._composite.events_topic}{note}')

    def _recover(self, _request, response, later: Later):
        state = self._fsm.state
        if state != 'Safety':
            return _answer(response, False, f'{self._name} is not in Safety ({state})')
        if self.parent_in_safety:
            return _answer(response, False, f'{self._name} is in Safety because its parent is: recover the '
                                            f'parent ({self._composite.parent_namespace}/coordinator/recover)')

        def checked(reasons: str) -> None:
            if reasons:
                later.answer(_answer(Trigger.Response(), False, f'the cause is still there: {reasons}'))
            elif self._fsm.state != 'Safety':
                later.answer(_answer(Trigger.Response(), False, f'{self._name} left Safety meanwhile '
                                                                f'({self._fsm.state})'))
            else:
                self._awaiting_running.append(later)
                causes = self._causes()
                self._node.get_logger().info(f'recovering from Safety: {causes}')
                self._raise_own(f'e_{self._name}_recovering', detail=causes)  # for the recording
                self._fsm.recover()
        self.check_faults(checked)
        return later

    def _stop(self, _request, response):
        state = self._fsm.state
        if state.startswith('Active.Stop'):
            return _answer(response, False, f'{self._name} is already stopping ({state})')
        detail = f'{self._node.get_fully_qualified_name()}/stop'
        if self._to_parent is None:
            self._raise_own(STOP_REQUESTED, detail=detail)
        else:
            self._to_parent.raise_event(STOP_REQUESTED, detail=detail)
        return _answer(response, True, 'stop requested: the application stops in order, from its root')

    # -- fault checks ---------------------------------------------------------------------------------

    def check_faults(self, then: Callable[[str], None]) -> None:
        """Ask whether the causes of this composite's Safety are gone (:mod:`.recovery`); ``then``
        gets why they are not ('' if they are). Joins a round already under way."""
        self._then.append(then)
        if self._check is not None:
            return
        self._number += 1
        children = list(self._fsm.children)
        self._check = FaultCheck(self._number, {COMPOSER, *children}, time.monotonic())
        self._raise_own(f'e_{self._name}_check_faults', detail=check_request(self._number, self.faults.own_sources()))
        for child in children:
            self._raise_own(f'e_{child}_check_faults', detail=check_request(self._number, []))

    def update(self) -> None:
        check = self._check
        now = time.monotonic()
        if check is not None and check.done(now):
            self._check, then, self._then = None, self._then, []
            reasons = check.outcome(now)
            for callback in then:
                callback(reasons)

    def _causes(self) -> str:
        return '; '.join(map(str, self.faults.faults)) or 'no fault recorded'

    # -- events the Coordinator hands over ------------------------------------------------------------

    def accepts(self, name: str) -> bool:
        """Events on this composite's topic the operator part handles."""
        return name == STOP_REQUESTED or name.endswith('_faults_checked')

    def consume(self, msg) -> bool:
        """Handle an event of this composite's topic; whether it was the operator part's."""
        if msg.name == STOP_REQUESTED:
            if self._to_parent is not None and msg.source != self._node.get_fully_qualified_name():
                self._to_parent.raise_event(STOP_REQUESTED, detail=msg.detail)  # on towards the root
            return True
        if not msg.name.endswith('_faults_checked'):
            return False
        party = msg.name.removeprefix('e_').removesuffix('_faults_checked')
        if party == self._name:
            if not msg.source.endswith('/composer'):
                return True
            party = COMPOSER
        number, reasons = parse_answer(msg.detail)
        if self._check is not None and number == str(self._check.number):
            self._check.answer(party, reasons)
            self.update()
        return True

    def consume_parent(self, msg) -> bool:
        """Handle a command of the parent; whether it was the operator part's."""
        name = msg.name
        if name == f'e_{self._name}_check_faults':
            number, _ = parse_request(msg.detail)

            def answer(reasons: str) -> None:
                self._to_parent.raise_event(f'e_{self._name}_faults_checked', detail=check_answer(number, reasons))
            self.check_faults(answer)
            return True
        if name == f'e_{self._name}_emergency':
            self.parent_in_safety = True
        elif name in (f'e_{self._name}_configure', f'e_{self._name}_stop'):
            self.parent_in_safety = False
        return False

    def processed(self, msg) -> None:
        """After the FSM processed ``msg``: a fault while in Safety is one of its causes."""
        if self._fsm.state == 'Safety' and is_fault(msg.name):
            self.faults.add(msg.name, msg.source, msg.detail)
            self._fail_recovery(f'{self._name} entered Safety again: {self._causes()}')

    def on_state(self, state: str, previous: str, safety_to_parent: tuple[str, ...]) -> None:
        if previous == 'Safety' and state != 'Safety':
            self.faults.clear()
        if state == 'Safety' and SAFETY_EVENT in safety_to_parent and self._to_parent is not None:
            self.parent_in_safety = True  # it was told to go to Safety
        if state.startswith('Active.Run.Running') and self._awaiting_running:
            waiting, self._awaiting_running = self._awaiting_running, []
            for later in waiting:
                later.answer(_answer(Trigger.Response(), True, f'{self._name} recovered: reconfigured, '
                                                               f'restarted, {state}'))
        elif state.startswith('Active.Stop'):
            self._fail_recovery(f'{self._name} is stopping ({state})')

    def _fail_recovery(self, why: str) -> None:
        waiting, self._awaiting_running = self._awaiting_running, []
        for later in waiting:
            later.answer(_answer(Trigger.Response(), False, why))


def _answer(response, success: bool, message: str):
    response.success = success
    response.message = message
    return response

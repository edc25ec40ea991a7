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
* ``compose`` (``itasc_msgs/srv/Compose``), offered by a composite whose model has composition
  steps, runs one of them (``e_<c>_compose_<step>``, :mod:`..composition.steps`) and answers with
  its result once the Composer gave it (``e_<c>_composed``: what changed; ``e_<c>_compose_failed``:
  why nothing did). Refused for a step the model does not have, and unless the composite is Running.

The Coordinator stays a pure event processor: the services only raise events and look at its FSM;
everything they start travels as events.
"""

from __future__ import annotations

import time
from typing import Callable, Iterable

from std_srvs.srv import Trigger

from itasc_msgs.srv import Compose, RaiseEvent

from ..communication.deferred_service import Later, create_deferred_service
from ..communication.event_names import (CHECK_FAULTS, CONFIGURE, EMERGENCY, FAULTS_CHECKED, RECOVERING,
                                          SAFETY_EVENT, STOP, STOP_REQUESTED, compose_step, event, owner_of)
from ..communication.events import EventRaiser
from ..entity import CompositeContext
from .lifecycle import LifecycleFsm
from .recovery import (COMPOSER, FaultCheck, Faults, check_answer, check_request, is_fault, parse_answer,
                       parse_request)

__all__ = ['Operator', 'OPERATOR', 'STOP_REQUESTED', 'quoted']

#: The source of the events an operator raises.
OPERATOR = 'operator'


class Operator:
    """The operator services of one Coordinator, and the fault checks before a recovery."""

    def __init__(self, node, *, composite: CompositeContext, fsm: LifecycleFsm, raise_own: Callable[..., None],
                 to_parent: EventRaiser | None, steps: Iterable[str] = (),
                 wake: Callable[[], None] = lambda: None) -> None:
        """``raise_own(name, detail=...)`` raises as the Coordinator on its composite's topic;
        ``to_parent`` on the parent's (None for the root); ``steps``: the composite's
        composition steps; ``wake()`` has :meth:`update` called soon and while :attr:`checking`."""
        self._node = node
        self._wake = wake
        self._composite = composite
        self._name = composite.name
        self._fsm = fsm
        self._raise_own = raise_own
        self._to_parent = to_parent
        self._operator = node.raiser(topic=composite.events_topic, source=OPERATOR)
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
        self._composition_steps = sorted(steps)
        self._composing: dict[str, list[Later]] = {}
        if self._composition_steps:  # a service is a reader and a writer that every endpoint of the process pairs with
            create_deferred_service(node, Compose, '~/compose', self._compose)

    # -- the services ---------------------------------------------------------------------------------

    def _raise_event(self, request, response):
        name = request.name.strip()
        allowed = self._fsm.running_events() | {SAFETY_EVENT}
        if not self._fsm.is_relevant(name):
            reacts = ', '.join(sorted(allowed))
            return _answer(response, False, f"no state of {self._name}'s Coordinator reacts to {quoted(name)}"
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
                self._raise_own(event(self._name, RECOVERING), detail=causes)  # for the recording
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

    def _compose(self, request, response, later: Later):
        step = request.step.strip()
        if step not in self._composition_steps:
            return _answer(response, False, f"{self._name} has no composition step {quoted(step)} "
                                            f'(steps: {", ".join(self._composition_steps) or "none"})')
        state = self._fsm.state
        if not state.startswith('Active.Run.Running'):
            return _answer(response, False, f'{self._name} is not Running ({state}): a step changes a running '
                                            'composite')
        self._composing.setdefault(step, []).append(later)
        self._operator.raise_event(compose_step(self._name, step))
        return later

    def composed(self, msg) -> None:
        """The Composer's answer to a composition step: to whoever asked for that step."""
        step, _, what = msg.detail.partition(':')
        success = msg.name.endswith('_composed')
        for later in self._composing.pop(step, []):
            later.answer(_answer(Compose.Response(), success, what.strip() if success else
                                 f'nothing changed: {what.strip()}'))

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
        self._wake()  # the check ends by its answers or its timeout, seen at the updates
        self._raise_own(event(self._name, CHECK_FAULTS), detail=check_request(self._number, self.faults.own_sources()))
        for child in children:
            self._raise_own(event(child, CHECK_FAULTS), detail=check_request(self._number, []))

    @property
    def checking(self) -> bool:
        """A fault check is under way (:meth:`update` ends it)."""
        return self._check is not None

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
        return name == STOP_REQUESTED or owner_of(name, FAULTS_CHECKED) is not None

    def consume(self, msg) -> bool:
        """Handle an event of this composite's topic; whether it was the operator part's."""
        if msg.name == STOP_REQUESTED:
            if self._to_parent is not None and msg.source != self._node.get_fully_qualified_name():
                self._to_parent.raise_event(STOP_REQUESTED, detail=msg.detail)  # on towards the root
            return True
        party = owner_of(msg.name, FAULTS_CHECKED)
        if party is None:
            return False
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
        if name == event(self._name, CHECK_FAULTS):
            number, _ = parse_request(msg.detail)

            def answer(reasons: str) -> None:
                self._to_parent.raise_event(event(self._name, FAULTS_CHECKED), detail=check_answer(number, reasons))
            self.check_faults(answer)
            return True
        if name == event(self._name, EMERGENCY):
            self.parent_in_safety = True
        elif name in (event(self._name, CONFIGURE), event(self._name, STOP)):
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


def quoted(text: str, *, limit: int = 80) -> str:
    """``text`` quoted for an answer, shortened past ``limit`` characters (a client's request is
    echoed, whatever it sent)."""
    if len(text) <= limit:
        return repr(text)
    return f'{text[:limit]!r}... ({len(text)} characters)'


def _answer(response, success: bool, message: str):
    response.success = success
    response.message = message
    return response

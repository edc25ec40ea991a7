"""Outside events (paper §3.1: Functional Entities know no one and broadcast their events; §6.2:
the Running sub-FSM moves on events): the entity that turns what other ROS nodes say into events
of its composite, so that a gripper node or a PLC bridge can drive the program.

One per composite whose model has ``events``, named ``outside_events``, deployed by the Composer
with the Monitors and not scheduled: it works on arrival. Per mapping (``OutsideEventModel``):

* a topic: every message raises the event; with ``field``/``value``, each message whose field
  equals the value after one that did not (or the first): a ``std_msgs/msg/Bool`` *turning* true
  raises it once, however often the gripper repeats it. Subscribed reliable, volatile, depth 10,
  as ``ros2 topic pub`` publishes.
* a service the composite offers (a relative name lies in the composite's namespace): every call
  raises the event (with ``field``/``value``, a call whose request field equals the value); a
  response with ``success``/``message`` (``std_srvs/srv/Trigger``, ``SetBool``) says what was done.

The event carries what caused it in its detail (``/gripper/grasped: data=True``).
"""

from __future__ import annotations

from functools import partial
from typing import Any, Iterable

from ..communication.interfaces import interface, read
from ..composition.model import OUTSIDE_EVENTS, OutsideEventModel
from ..entity import CompositeContext, Entity

__all__ = ['OutsideEvents']


class OutsideEvents(Entity):
    """Raises events of its composite on other nodes' messages and service calls."""

    def __init__(self, *, composite: CompositeContext, events: Iterable[OutsideEventModel]) -> None:
        super().__init__(OUTSIDE_EVENTS, composite=composite)
        self.events = list(events)
        self._matched: dict[int, bool] = {}
        for k, spec in enumerate(self.events):
            cls = interface(spec.type, spec.kind)
            if spec.topic is not None:
                self.create_subscription(cls, spec.topic, partial(self._on_message, k), 10)
            else:
                self.create_service(cls, spec.service or '', partial(self._on_call, k))

    def _on_message(self, k: int, msg: Any) -> None:
        spec = self.events[k]
        if spec.field is None:
            self.raise_event(spec.event, detail=spec.topic or '')
            return
        value = read(msg, spec.field)
        matches = value == spec.value
        if matches and not self._matched.get(k, False):
            self.raise_event(spec.event, detail=f'{spec.topic}: {spec.field}={value}')
        self._matched[k] = matches

    def _on_call(self, k: int, request: Any, response: Any) -> Any:
        spec = self.events[k]
        value = read(request, spec.field) if spec.field is not None else None
        matches = spec.field is None or value == spec.value
        if matches:
            self.raise_event(spec.event, detail=f'{spec.service}' + (f': {spec.field}={value}' if spec.field else ''))
        if hasattr(response, 'success'):
            response.success = matches
        if hasattr(response, 'message'):
            response.message = f'raised {spec.event}' if matches else \
                f'nothing raised: {spec.field} is {value!r}, not {spec.value!r}'
        return response

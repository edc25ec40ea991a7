"""What a Running sub-FSM waits for from outside (paper §6.2: the Running sub-FSM moves on events;
issue #14: events another ROS node raises, mapped in the model's ``events``).

A program that waits for a gripper or a PLC which is not there looks hung: the robot holds still and
nothing is printed. Once a composite has stayed for :data:`WAIT_NOTICE` seconds in a state of its
Running sub-FSM that only an outside event leaves, the console says so, once per entry into the
state, with the command that raises the event by hand::

    [waiting] itasc: in wait_for_gripper for 5 s; it moves on at e_object_grasped: ros2 topic pub
    --once /gripper/object_grasped std_msgs/msg/Bool "{data: true}", or ros2 service call
    /pick_with_gripper/itasc/object_grasped std_srvs/srv/Trigger
"""

from __future__ import annotations

import json
import time
from typing import Any, Callable

from itasc_core.composition.model import CompositeModel, OutsideEventModel, walk

from .facts import RunFacts, Transition

__all__ = ['Waits', 'WAIT_NOTICE', 'how_to_raise']

#: How long a composite stays in a state before the console says what it waits for [s].
WAIT_NOTICE = 5.0


def _yaml_value(value: Any) -> str:
    """As YAML inside a double-quoted shell word: strings in single quotes."""
    if isinstance(value, str):
        return "'" + value.replace("'", "''") + "'"
    return json.dumps(value)  # true/false and numbers


def _request(field: str | None, value: Any) -> str:
    """``a.b`` = v as the YAML ``{a: {b: v}}`` that ``ros2 topic pub`` and ``ros2 service call`` take."""
    if field is None:
        return ''
    text = _yaml_value(value)
    for part in reversed(field.split('.')):
        text = f'{{{part}: {text}}}'
    return f' "{text}"'


def how_to_raise(spec: OutsideEventModel, *, namespace: str) -> str:
    """The ``ros2`` command that raises ``spec``'s event in the composite of ``namespace``."""
    if spec.topic is not None:
        topic = spec.topic if spec.topic.startswith('/') else f'{namespace}/{spec.topic}'
        return f'ros2 topic pub --once {topic} {spec.type}{_request(spec.field, spec.value)}'
    service = spec.service or ''
    service = service if service.startswith('/') else f'{namespace}/{service}'
    return f'ros2 service call {service} {spec.type}{_request(spec.field, spec.value)}'


class Waits:
    """Says which outside events a composite waits for, once it has waited ``after`` seconds."""

    def __init__(self, model: CompositeModel, *, after: float = WAIT_NOTICE,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self._after, self._clock = after, clock
        #: composite -> state -> the event sets that leave it (a transition needs all of a set)
        self._leaving: dict[str, dict[str, list[tuple[str, ...]]]] = {}
        #: composite -> outside event -> the commands that raise it
        self._outside: dict[str, dict[str, list[str]]] = {}
        for namespace, composite in walk(model):
            for spec in composite.events:
                self._outside.setdefault(composite.name, {}).setdefault(spec.event, []).append(
                    how_to_raise(spec, namespace=namespace))
            if composite.running is not None:
                states = self._leaving.setdefault(composite.name, {})
                for transition in composite.running.transitions:
                    states.setdefault(transition.source, []).append(tuple(transition.when))
        self._in: dict[str, tuple[str, float]] = {}

    def on_transition(self, tr: Transition) -> None:
        state = RunFacts.sub_state(tr.state)
        if state is None:
            self._in.pop(tr.composite, None)
        else:
            self._in[tr.composite] = (state, self._clock())

    def due(self) -> list[str]:
        """The lines to show now (each composite's wait once per entry into its state)."""
        lines = []
        now = self._clock()
        for composite, (state, since) in list(self._in.items()):
            if now - since < self._after:
                continue
            del self._in[composite]
            line = self._line(composite, state, now - since)
            if line is not None:
                lines.append(line)
        return lines

    def _line(self, composite: str, state: str, waited: float) -> str | None:
        outside = self._outside.get(composite, {})
        ways = self._leaving.get(composite, {}).get(state, [])
        if not ways or not all(any(e in outside for e in when) for when in ways):
            return None  # a state its own Monitors (also) leave: the program's business
        moves = ' or '.join(' and '.join(when) for when in ways)
        commands = ', or '.join(c for when in ways for e in when for c in outside.get(e, []))
        return f'[waiting] {composite}: in {state} for {waited:.0f} s; it moves on at {moves}: {commands}'

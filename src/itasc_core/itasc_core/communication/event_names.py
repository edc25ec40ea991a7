"""How events are named and addressed (paper §3.1 boundary of knowledge, §6.1, §7.2).

One rule, used by every Coordinator and by the model transforms: a parent addresses a child
composite by prefixing the child's name, ``e_<child>_<x>``, on the parent's event topic. The child's
Coordinator either reacts to that command in its own life-cycle FSM (``e_<child>_configure``,
``e_<child>_high_accuracy_control`` where the child's Running sub-FSM has such a transition), or
passes it into its composite as ``e_<x>``, where its own entities (Configurator, Scheduler)
react. A parent knows its children, never their insides; and since the prefix is the child's
name, an event meant for one child never reaches another.

Priority events (processed on arrival, §6.2): ``e_emergency`` and the command that puts a child
into Safety, ``e_<child>_emergency``.
"""

from __future__ import annotations

__all__ = ['SAFETY_EVENT', 'to_child', 'from_parent', 'is_addressed_to', 'is_priority']

SAFETY_EVENT = 'e_emergency'


def to_child(child: str, event: str) -> str:
    """The name under which a parent commands ``event`` (``e_<x>`` or ``<x>``) to ``child``."""
    return f'e_{child}_{event.removeprefix("e_")}'


def is_addressed_to(child: str, name: str) -> bool:
    return name.startswith(f'e_{child}_')


def from_parent(child: str, name: str) -> str:
    """The event a parent's command ``e_<child>_<x>`` becomes inside ``child``: ``e_<x>``."""
    return 'e_' + name.removeprefix(f'e_{child}_')


def is_priority(name: str) -> bool:
    return name == SAFETY_EVENT or name.endswith('_emergency')

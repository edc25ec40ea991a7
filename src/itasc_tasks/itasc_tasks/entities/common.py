"""What the Functional Entities of a Task composite share (paper §4.2 "Task", Fig. 2): the
semantics of their ports and how they notice that their Task was (re)activated.

The Task's entities exchange labelled tables (:mod:`itasc_core.itasc.entities.messages`) whose
semantics name the Task, e.g. ``Output(ApproachObject)``; what leaves the Task towards the Solver
is ``ConstraintRows`` on the program-wide joint velocities.
"""

from __future__ import annotations

from typing import Any

from std_msgs.msg import Float64MultiArray

from itasc_core.communication.ports import PortSpec

__all__ = ['table_port', 'Ticks', 'names']


def table_port(name: str, direction: str, kind: str, task: str) -> PortSpec:
    """A labelled-table port of Task ``task`` carrying ``kind`` (e.g. 'Features', 'Output')."""
    return PortSpec(name=name, direction=direction, msg_type=Float64MultiArray, type=kind.lower(),
                    semantics=f'{kind}({task})')


class Ticks:
    """Tick bookkeeping: the time step, and whether the entity resumes after a pause (its Task was
    deactivated by the Coordinator, so its Scheduler skipped it) or runs for the first time."""

    def __init__(self) -> None:
        self.last: float | None = None
        self.period = 0.0

    def step(self, t: float) -> tuple[float, bool]:
        if self.last is None:
            self.last = t
            return 0.0, True
        dt = t - self.last
        self.last = t
        resumed = self.period > 0.0 and dt > 2.5 * self.period
        if not resumed and dt > 0.0:
            self.period = dt
        return (self.period if resumed else dt), resumed


def names(values: list[Any]) -> list[str]:
    """A string-list parameter without its placeholder entries."""
    return [v for v in values if v]

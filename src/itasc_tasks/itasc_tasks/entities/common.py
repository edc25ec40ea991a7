"""What the Functional Entities of a Task composite share (paper §4.2 "Task", Fig. 2): the
semantics of their ports and how they notice that their Task was (re)activated.

The Task's entities exchange typed samples (:mod:`itasc_core.itasc.entities.messages`: features
and outputs with their Jacobian, setpoints, control) whose semantics name the Task, e.g.
``Output(ApproachObject)``; what leaves the Task towards the Solver is ``ConstraintRows`` on the
program-wide joint velocities.
"""

from __future__ import annotations

from typing import Annotated

from itasc_msgs.msg import Control, Features, Setpoint
from pydantic import Field

from itasc_core.communication.ports import PortSpec

__all__ = ['task_port', 'Ticks', 'TaskName']

#: The parameter naming the Task an entity belongs to: read-only, since its ports' semantics and
#: topics are made from it (another Task is another composite).
TaskName = Annotated[str, Field(frozen=True)]

#: The message of each kind of data a Task's entities exchange.
_MESSAGES = {'Features': Features, 'Output': Features, 'Setpoint': Setpoint, 'Control': Control}


def task_port(name: str, direction: str, kind: str, task: str) -> PortSpec:
    """A port of Task ``task`` carrying ``kind`` ('Features', 'Output', 'Setpoint' or 'Control')."""
    return PortSpec(name=name, direction=direction, msg_type=_MESSAGES[kind], type=kind.lower(),
                    semantics=f'{kind}({task})')


class Ticks:
    """Tick bookkeeping: the time step, and whether the entity runs for the first time or resumes
    after its Task was switched off and on again (:meth:`restart`, from the entity's ``activate``)."""

    def __init__(self, period: float) -> None:
        self.period = period
        self.last: float | None = None
        self._resume = False

    def restart(self) -> None:
        self._resume = True

    def reset(self) -> None:
        """As new: the next tick is a first one (a start, or a restart after Safety)."""
        self.last, self._resume = None, False

    def step(self, t: float) -> tuple[float, bool]:
        """``(dt, resumed)`` for the tick at time ``t``; dt is the nominal period after a restart."""
        last, self.last = self.last, t
        if last is None:
            return 0.0, True
        if self._resume:
            self._resume = False
            return self.period, True
        return t - last, False


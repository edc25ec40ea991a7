"""Coordination (paper §6): the life-cycle FSM, the Coordinator, the Scheduler and the Timer."""

from .coordinator import Coordinator
from .lifecycle import LifecycleFsm, RunningFsmSpec, RunningState, RunningTransition
from .scheduler import Scheduler
from .timer import Timer

__all__ = ['Coordinator', 'LifecycleFsm', 'RunningFsmSpec', 'RunningState', 'RunningTransition', 'Scheduler',
           'Timer']

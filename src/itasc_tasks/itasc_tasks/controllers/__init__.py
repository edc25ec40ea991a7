"""Constraint Controllers (paper §4.1 "CC"): the control laws a Task's controller runs, a category of
the registry of kinds (:mod:`itasc_core.kinds`, entry point group ``itasc.controllers``).

A controller kind is a :class:`ConstraintController`: its gains (its parameter model: a Task's
``controller`` section and the CC entity's ROS parameters), the law and what it forgets on
``reset``. Adding one is a file with its class and a line in ``setup.py``. The rules around a law
(the error, the inequality bounds) are :mod:`itasc_tasks.constraint_controller`'s.
"""

from __future__ import annotations

from .kind import CONTROLLERS, ConstraintController, Gains, saturate
from .p import PController
from .pid import PIDController

__all__ = ['ConstraintController', 'CONTROLLERS', 'Gains', 'PController', 'PIDController', 'saturate']

"""Driver kinds (paper §4.1 "Driver", §4.2: the hardware a program runs on), a category of the
registry of kinds (:mod:`itasc_core.kinds`, entry point group ``itasc.drivers``).

A Driver kind is a :class:`Driver`: its fields in the application's ``drivers`` section, the
Functional Entity that runs it (with the ports of :mod:`itasc_drivers.ports`), and the step of the
model transform that gives that entity its parameters. Adding one is a file with its class and a
line in ``setup.py``.
"""

from __future__ import annotations

from .kind import DRIVERS, Driver, DrivenRobot

__all__ = ['Driver', 'DRIVERS', 'DrivenRobot']

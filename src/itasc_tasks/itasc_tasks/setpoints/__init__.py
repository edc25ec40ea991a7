"""Setpoint Generator kinds (paper §4.1: desired values for a Task's controller), a category of the
registry of kinds (:mod:`itasc_core.kinds`, entry point group ``itasc.setpoint_generators``).

A kind is a :class:`SetpointKind`: its fields (a Task's ``setpoint`` section and the Setpoint
Generator entity's ROS parameters) and the generator it makes of them (the generators themselves
are :mod:`itasc_tasks.setpoint_generator`'s). Adding one is a file with its class and a line in
``setup.py``.
"""

from __future__ import annotations

from .kind import SETPOINTS, SetpointKind, Target

__all__ = ['SetpointKind', 'SETPOINTS', 'Target']

"""Monitor conditions (paper §4.1 "Monitors": "compare actual data flow with what is expected"),
a category of the registry of kinds (:mod:`itasc_core.kinds`, entry point group ``itasc.conditions``).

A condition kind is a :class:`Condition`: its parameter model (the Monitor's section of the
application model and the Monitor entity's ROS parameters, e.g. ``threshold``) and ``holds``, plain
Python, testable without ROS. Adding one is a file with its class and a line in ``setup.py``.
"""

from __future__ import annotations

from .kind import CONDITIONS, Condition

__all__ = ['Condition', 'CONDITIONS']

"""Task types (paper §4.1 "VKC", §4.2 "Task"): the kinds of virtual kinematic chain a Task is
built on, a category of the registry of kinds (:mod:`itasc_core.kinds`, entry point group
``itasc.task_types``). Adding one is a file with its :class:`TaskType` and a line in ``setup.py``."""

from __future__ import annotations

from .kind import TASK_TYPES, FramePair, TaskType

__all__ = ['TaskType', 'TASK_TYPES', 'FramePair']
